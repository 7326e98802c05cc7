"""The tracker's state as arrays: the detections of a step and the table of tracks.

Both are column-oriented (one numpy array per field, one row per detection or track)
so that every step costs a handful of vectorised operations, whatever the number of
people. :class:`TrackTable` is the per-track state that the tracker's late-batch replay
restores; a column added here is restored with the rest.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from openptrack_py.messages.detection import DetectionBatch

HISTORY = 48
"""Past positions kept per track (for the velocity measurement)."""
HISTORY_SPACING_S = 0.04
"""Least time between two remembered positions of a track."""


@dataclass(frozen=True)
class DetectionArrays:
    """The detections of one batch that the tracker uses, as arrays.

    Parameters
    ----------
    index : ndarray
        Position of each kept detection in the batch.
    xy, z, height, confidence, distance : ndarray
        Per-detection values.
    """

    index: np.ndarray
    xy: np.ndarray
    z: np.ndarray
    height: np.ndarray
    confidence: np.ndarray
    distance: np.ndarray

    def __len__(self) -> int:
        return len(self.index)

    def subset(self, rows: np.ndarray) -> DetectionArrays:
        """The detections at ``rows`` (indices or a mask), in that order."""
        return DetectionArrays(
            index=self.index[rows],
            xy=self.xy[rows],
            z=self.z[rows],
            height=self.height[rows],
            confidence=self.confidence[rows],
            distance=self.distance[rows],
        )

    @classmethod
    def from_batch(cls, batch: DetectionBatch, min_confidence: float) -> DetectionArrays:
        """Arrays of the batch's detections at least ``min_confidence`` confident."""
        kept = [(i, d) for i, d in enumerate(batch.detections) if d.confidence >= min_confidence]
        if not kept:
            empty = np.zeros(0)
            return cls(np.zeros(0, dtype=int), np.zeros((0, 2)), empty, empty, empty, empty)
        rows = np.array([(d.x, d.y, d.z, d.height, d.confidence, d.distance) for _, d in kept])
        return cls(
            index=np.array([i for i, _ in kept]),
            xy=rows[:, 0:2],
            z=rows[:, 2],
            height=rows[:, 3],
            confidence=rows[:, 4],
            distance=rows[:, 5],
        )


@dataclass
class TrackTable:
    """Every track's state, as parallel arrays (one row per track)."""

    ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    x: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    cov: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    z: np.ndarray = field(default_factory=lambda: np.zeros(0))
    height: np.ndarray = field(default_factory=lambda: np.zeros(0))
    confidence: np.ndarray = field(default_factory=lambda: np.zeros(0))
    first_seen: np.ndarray = field(default_factory=lambda: np.zeros(0))
    last_seen: np.ndarray = field(default_factory=lambda: np.zeros(0))
    hits: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    confirmed: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    hist_t: np.ndarray = field(default_factory=lambda: np.zeros((0, HISTORY)))
    hist_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, HISTORY, 2)))

    COLUMNS = (
        "ids", "x", "cov", "z", "height", "confidence", "first_seen", "last_seen", "hits",
        "confirmed", "hist_t", "hist_xy",
    )  # fmt: skip

    def __len__(self) -> int:
        return len(self.ids)

    def keep(self, mask: np.ndarray) -> None:
        """Drop the rows where ``mask`` is False."""
        for name in self.COLUMNS:
            setattr(self, name, getattr(self, name)[mask])

    def copy(self) -> TrackTable:
        """An independent copy."""
        return TrackTable(**{name: getattr(self, name).copy() for name in self.COLUMNS})

    def append(self, **rows: np.ndarray) -> None:
        """Add rows (one array per column, same length)."""
        for name in self.COLUMNS:
            setattr(self, name, np.concatenate([getattr(self, name), rows[name]]))
