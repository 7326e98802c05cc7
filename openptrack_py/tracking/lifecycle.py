"""Which detections start tracks, when tracks are confirmed, and when they are deleted."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from openptrack_py.tracking.state import DetectionArrays, TrackTable


@dataclass(frozen=True)
class ConfidenceInitiator:
    """Start tentative tracks from confident detections no track can explain.

    A detection starts a track when it was not associated, its confidence is at least
    ``min_confidence``, and it lies outside every existing track's gate (a second blob
    of someone already tracked, or the same person seen by an overlapping sensor, never
    starts a second track). A tentative track is confirmed after
    ``detections_to_validate`` associated detections.

    Parameters
    ----------
    min_confidence : float
        Least confidence of a detection that starts a track.
    detections_to_validate : int
        Associated detections (the first included) needed for confirmation.
    """

    min_confidence: float
    detections_to_validate: int

    def initiate(
        self, dets: DetectionArrays, assigned: np.ndarray, in_any_gate: np.ndarray
    ) -> np.ndarray:
        """Indices of the detections that start new tracks."""
        confident = dets.confidence >= self.min_confidence
        return np.flatnonzero(~assigned & ~in_any_gate & confident)

    def confirm(self, table: TrackTable, t: float) -> np.ndarray:
        """Confirmation flags after the step at ``t``."""
        return table.confirmed | (table.hits >= self.detections_to_validate)


@dataclass(frozen=True)
class TimeDeleter:
    """Delete tracks that are stale.

    Parameters
    ----------
    sec_before_fake : float
        A tentative track still unconfirmed this long after its first detection goes.
    sec_before_old : float
        A confirmed track unseen this long goes.
    tentative_timeout_s : float
        A tentative track unseen this long goes: the detections that confirm a track must
        come close together, as a real person's do (a sensor sees them every frame),
        not scattered like clutter.
    """

    sec_before_fake: float
    sec_before_old: float
    tentative_timeout_s: float = float("inf")

    def delete(self, table: TrackTable, t: float) -> np.ndarray:
        """Mask of tracks to delete at time ``t``."""
        confirmed = table.confirmed
        fake = ~confirmed & (
            (t - table.first_seen >= self.sec_before_fake)
            | (t - table.last_seen >= self.tentative_timeout_s)
        )
        old = confirmed & (t - table.last_seen >= self.sec_before_old)
        return fake | old
