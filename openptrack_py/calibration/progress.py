"""Progress of a board session: what a capture loop shows while the board is moved.

Supports the capture of the checkerboard calibration of Munaro et al., OpenPTrack (§4):
:class:`CalibrationProgress` is the running tally that a capture loop (the CLI, a web
page) polls while someone moves the board: who sees it now, views per pair so far,
image coverage per sensor, and whether the sensors are linked yet
(:func:`~openptrack_py.calibration.posegraph.connected_groups`). Synchronised captures
(the simulator's) come through :meth:`CalibrationProgress.update`; the still views of
unsynchronised sensors (a live or recorded session) through
:meth:`CalibrationProgress.observe`.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from openptrack_py.calibration.observations import BoardObservation
from openptrack_py.calibration.posegraph import connected_groups
from openptrack_py.errors import CalibrationError

__all__ = ["CalibrationProgress", "ProgressSnapshot"]


@dataclass(frozen=True)
class ProgressSnapshot:
    """What a capture loop has gathered so far (for the CLI and the web page).

    Parameters
    ----------
    stamp : float or None
        The latest capture's stamp.
    seeing : tuple of str
        Sensors that see the board in the latest capture.
    views : dict
        Per sensor: captures in which it saw the board.
    pair_views : dict
        Per pair (ids sorted): captures both saw.
    coverage : dict
        Per sensor: share of the cells of a ``grid x grid`` division of its image where
        corners were seen.
    connected : bool
        Every sensor linked to the others by pairs of at least ``min_shared_views``.
    """

    stamp: float | None
    seeing: tuple[str, ...]
    views: dict[str, int]
    pair_views: dict[tuple[str, str], int]
    coverage: dict[str, float]
    connected: bool

    def to_dict(self) -> dict:
        """JSON-ready dict (pairs as ``"a|b"`` keys)."""
        return {
            "stamp": self.stamp,
            "seeing": list(self.seeing),
            "views": dict(self.views),
            "pair_views": {f"{a}|{b}": n for (a, b), n in self.pair_views.items()},
            "coverage": dict(self.coverage),
            "connected": self.connected,
        }


class CalibrationProgress:
    """Running tally of a board session, safe to poll from another thread.

    Parameters
    ----------
    image_sizes : mapping of str to (int, int)
        Every sensor's image ``(width, height)``.
    grid : int
        Cells per image side for the coverage figure.
    min_shared_views : int
        Fewest shared captures that link two sensors (for ``connected``).
    pair_within_s : float
        Two sensors' still views this close in time are of one placement
        (:meth:`observe`).
    """

    def __init__(
        self,
        image_sizes: Mapping[str, tuple[int, int]],
        *,
        grid: int = 4,
        min_shared_views: int = 3,
        pair_within_s: float = 0.5,
    ) -> None:
        self._sizes = dict(image_sizes)
        self._grid = grid
        self._min_shared = min_shared_views
        self._cells = {s: np.zeros((grid, grid), dtype=bool) for s in self._sizes}
        self._views = dict.fromkeys(self._sizes, 0)
        self._pairs: dict[tuple[str, str], int] = {}
        self._stamp: float | None = None
        self._seeing: tuple[str, ...] = ()
        self._pair_within_s = pair_within_s
        self._view_stamps: list[tuple[str, float]] = []
        self._lock = threading.Lock()

    def update(
        self, stamp: float, detections: Mapping[str, np.ndarray | None]
    ) -> ProgressSnapshot:
        """Add one capture: each sensor's corners ``(n, 2)``, or None where not seen.

        Raises
        ------
        CalibrationError
            For a sensor not given at construction.
        """
        self._check_known(detections)
        seeing = tuple(s for s in self._sizes if detections.get(s) is not None)
        with self._lock:
            self._stamp = stamp
            self._seeing = seeing
            for s in seeing:
                self._views[s] += 1
                self._mark(s, np.asarray(detections[s], dtype=float))
            for pair in combinations(sorted(seeing), 2):
                self._pairs[pair] = self._pairs.get(pair, 0) + 1
        return self.snapshot()

    def observe(
        self, stamp: float, seeing: Sequence[str], views: Sequence[BoardObservation]
    ) -> ProgressSnapshot:
        """Who sees the board now, and the still views completed since the last call.

        For unsynchronised sensors (a live or recorded session): a view counts for a
        pair when the other sensor completed one within ``pair_within_s`` of it (the
        same placement of the board), once per placement.

        Raises
        ------
        CalibrationError
            For a sensor not given at construction.
        """
        self._check_known([*seeing, *(v.sensor_id for v in views)])
        now = set(seeing)
        with self._lock:
            self._stamp = stamp
            self._seeing = tuple(s for s in self._sizes if s in now)
            for view in views:
                sid = view.sensor_id
                self._views[sid] += 1
                self._mark(sid, np.asarray(view.corners, dtype=float))
                partners = {
                    other
                    for other, when in self._view_stamps
                    if other != sid and abs(when - view.stamp) <= self._pair_within_s
                }
                for other in partners:
                    pair = (min(sid, other), max(sid, other))
                    self._pairs[pair] = self._pairs.get(pair, 0) + 1
                self._view_stamps.append((sid, view.stamp))
        return self.snapshot()

    def _check_known(self, sensors: Iterable[str]) -> None:
        unknown = [s for s in sensors if s not in self._sizes]
        if unknown:
            raise CalibrationError(
                f"calibration progress: unknown sensor {unknown[0]!r} "
                f"(sensors: {', '.join(self._sizes)})"
            )

    def _mark(self, sensor: str, corners: np.ndarray) -> None:
        """Mark the image cells where corners were seen."""
        width, height = self._sizes[sensor]
        g = self._grid
        col = np.clip((corners[:, 0] + 0.5) * g // width, 0, g - 1).astype(int)
        row = np.clip((corners[:, 1] + 0.5) * g // height, 0, g - 1).astype(int)
        self._cells[sensor][row, col] = True

    def snapshot(self) -> ProgressSnapshot:
        """The tally so far."""
        with self._lock:
            groups = connected_groups(list(self._sizes), self._pairs, self._min_shared)
            return ProgressSnapshot(
                stamp=self._stamp,
                seeing=self._seeing,
                views=dict(self._views),
                pair_views=dict(self._pairs),
                coverage={s: float(c.mean()) for s, c in self._cells.items()},
                connected=len(groups) == 1,
            )
