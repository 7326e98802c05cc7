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
SENSOR_SLOTS = 16
"""Sensors whose last detection of each track is remembered one by one."""


def sensor_slot(sensor_index: int) -> int:
    """The column of ``TrackTable.sensor_hit_t`` of a sensor (by index)."""
    return min(sensor_index, SENSOR_SLOTS - 1)


@dataclass(frozen=True)
class DetectionArrays:
    """The detections of one batch that the tracker uses, as arrays.

    Parameters
    ----------
    index : ndarray
        Position of each kept detection in the batch.
    xy, z, height, confidence, distance : ndarray
        Per-detection values.
    sensor_id : str
        The sensor of the batch.
    seq : int
        The batch's sequence number.
    """

    index: np.ndarray
    xy: np.ndarray
    z: np.ndarray
    height: np.ndarray
    confidence: np.ndarray
    distance: np.ndarray
    sensor_id: str = ""
    seq: int = -1

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
            sensor_id=self.sensor_id,
            seq=self.seq,
        )

    @classmethod
    def from_batch(cls, batch: DetectionBatch, min_confidence: float) -> DetectionArrays:
        """Arrays of the batch's detections at least ``min_confidence`` confident."""
        kept = [(i, d) for i, d in enumerate(batch.detections) if d.confidence >= min_confidence]
        if not kept:
            empty = np.zeros(0)
            return cls(
                np.zeros(0, dtype=int), np.zeros((0, 2)), empty, empty, empty, empty,
                batch.sensor_id, batch.seq,
            )  # fmt: skip
        rows = np.array([(d.x, d.y, d.z, d.height, d.confidence, d.distance) for _, d in kept])
        return cls(
            index=np.array([i for i, _ in kept]),
            xy=rows[:, 0:2],
            z=rows[:, 2],
            height=rows[:, 3],
            confidence=rows[:, 4],
            distance=rows[:, 5],
            sensor_id=batch.sensor_id,
            seq=batch.seq,
        )


@dataclass
class TrackTable:
    """Every track's state, as parallel arrays (one row per track).

    Parameters
    ----------
    ids : ndarray of int
        Track ids, never reused.
    x, cov : ndarray
        UKF state ``[x, y, vx, vy]`` and its covariance.
    z, height : ndarray
        Smoothed centroid height and person height, metres.
    confidence : ndarray
        Exponential average of the detector confidence of the track's detections.
    first_seen, last_seen : ndarray
        Time of the first detection, and of the last confident one.
    hits : ndarray of int
        Confident detections so far.
    confirmed : ndarray of bool
        Whether the track is confirmed (published).
    hist_t, hist_xy : ndarray
        Remembered past positions (for the velocity measurement).
    support : ndarray
        Share of the recent frames of the sensors that should see the track that did
        detect it (exponential average): how well the evidence holds up.
    birth_xy : ndarray
        Mean position of the track's first detections: where it started.
    birth_n : ndarray of int
        Detections averaged into ``birth_xy`` so far.
    recent_xy : ndarray
        Exponential average of the positions of the track's recent detections (where
        the evidence says it is, unlike the filter's prediction while unseen).
    last_sensor : ndarray of int
        Index of the sensor of the track's last detection.
    multi_t : ndarray
        Last time the track's detections came from two different sensors in a row.
    evidence : ndarray
        Log-likelihood ratio of "a person" against "a static false positive" from the
        track's detections and misses in the frames of the sensors that should see it
        (a sequential probability ratio test; see ``lifecycle``).
    sensor_hit_t : ndarray
        ``(n, SENSOR_SLOTS)`` last time each sensor (by index; later sensors share the
        last slot) detected the track; ``-inf`` for never.
    """

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
    support: np.ndarray = field(default_factory=lambda: np.zeros(0))
    birth_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    birth_n: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    recent_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    last_sensor: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    multi_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    evidence: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sensor_hit_t: np.ndarray = field(default_factory=lambda: np.zeros((0, SENSOR_SLOTS)))

    COLUMNS = (
        "ids", "x", "cov", "z", "height", "confidence", "first_seen", "last_seen", "hits",
        "confirmed", "hist_t", "hist_xy", "support", "birth_xy", "birth_n", "recent_xy",
        "last_sensor", "multi_t", "evidence", "sensor_hit_t",
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
