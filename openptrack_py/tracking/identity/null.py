"""The identity role's default: no identity model at all.

With :class:`NullIdentity` the tracker associates on motion alone and publishes no
``stable_id`` or name. Identity models (appearance, re-identification, a roster of
named people) implement :class:`~openptrack_py.tracking.base.IdentityModel` in its place.
"""

from __future__ import annotations

import numpy as np

from openptrack_py.tracking.state import DetectionArrays, TrackTable


class NullIdentity:
    """An identity role that has no opinion and keeps no state."""

    needs_looks = False

    def cost(
        self, table: TrackTable, dets: DetectionArrays, t: float, allowed: np.ndarray
    ) -> np.ndarray | None:
        """No extra association cost."""
        return None

    def observe(
        self,
        table: TrackTable,
        rows: np.ndarray,
        cols: np.ndarray,
        dets: DetectionArrays,
        t: float,
        certain: np.ndarray | None = None,
    ) -> None:
        """Nothing to learn."""

    def started(
        self, table: TrackTable, rows: np.ndarray, dets: DetectionArrays, t: float
    ) -> None:
        """Nothing to set up."""

    def ended(
        self, table: TrackTable, rows: np.ndarray, t: float, reason: str = "deleted"
    ) -> None:
        """Nothing to forget."""

    def handed_over(self, table: TrackTable) -> np.ndarray:
        """No track is known to follow someone else."""
        return np.zeros(0, dtype=np.int64)

    def distinct(self, table: TrackTable, rows_a: np.ndarray, rows_b: np.ndarray) -> np.ndarray:
        """Nothing known: no pair is known to be two people."""
        return np.zeros(len(rows_a), dtype=bool)

    def shares(
        self,
        table: TrackTable,
        lonely: np.ndarray,
        partner: np.ndarray,
        dets: DetectionArrays,
        cols: np.ndarray,
        t: float,
    ) -> np.ndarray:
        """No track shares another's detection."""
        return np.zeros(len(lonely), dtype=bool)

    def labels(self, ids: np.ndarray) -> tuple[list[None], list[None]]:
        """No ``stable_id`` and no name for any track."""
        return [None] * len(ids), [None] * len(ids)
