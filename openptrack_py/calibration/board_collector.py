"""The master's side of a checkerboard session: every sensor's reports into views.

Gathers the :class:`~openptrack_py.calibration.board_wire.BoardReport` of every sensor
(live over Zenoh, or made from recordings on the spot): the still views they completed,
their intrinsics, and who sees the board now, which it feeds to a progress display
(:class:`~openptrack_py.calibration.progress.CalibrationProgress` or anything with its
``observe``) with every completed view and every ``every_s`` seconds. Time is the
reports' stamps for a recorded session, the arrival time for a live one (the sensors'
clocks and paces differ; who sees the board *now* is a matter of arrival). Reports
from a sensor the network does not list, on another sensor's key, or malformed are
counted and dropped; they change nothing. Safe to feed from a transport thread.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterable, Sequence
from dataclasses import replace
from typing import Any, Protocol

from openptrack_py.calibration.board_wire import BoardReport, decode_board_report
from openptrack_py.calibration.observations import BoardObservation
from openptrack_py.detection.frame import Intrinsics
from openptrack_py.errors import WireFormatError

__all__ = ["BoardCollector"]

PROGRESS_EVERY_S = 0.5
"""Report time between two progress updates."""
SEEN_WITHIN_S = 0.25
"""A sensor sees the board now if it found it this recently."""
MAX_VIEWS_PER_SENSOR = 500
"""A session has tens of placements: more views from one sensor are a flood, dropped."""


class ProgressDisplay(Protocol):
    """What the collector updates: a tally of who sees the board and of the views."""

    def observe(
        self, stamp: float, seeing: Sequence[str], views: Sequence[BoardObservation]
    ) -> Any:
        """Who sees the board now, and the views completed since the last call."""


class BoardCollector:
    """Views, intrinsics and progress of one board session.

    Parameters
    ----------
    sensors : iterable of str
        The sensors taking part (the network's).
    progress : ProgressDisplay or None
        Updated as the reports come.
    every_s : float
        Report time between two progress updates.
    board : tuple of (int, int, float), optional
        The board expected (rows, columns, square side): a view of another board is
        counted as ``other_board`` and dropped (its sensor is in :attr:`other_board`).
    """

    def __init__(
        self,
        sensors: Iterable[str],
        progress: ProgressDisplay | None = None,
        every_s: float = PROGRESS_EVERY_S,
        board: tuple[int, int, float] | None = None,
    ) -> None:
        self.sensors = tuple(sensors)
        self.progress = progress
        self.every_s = every_s
        self.board = board
        self.counts = {"reports": 0, "views": 0, "malformed": 0, "wrong_key": 0, "unknown": 0,
                       "other_board": 0, "too_many_views": 0}  # fmt: skip
        self._views_of: dict[str, int] = {}
        self.other_board: dict[str, tuple[int, int, float]] = {}
        self._views: list[BoardObservation] = []
        self._intrinsics: dict[str, Intrinsics] = {}
        self._latest: dict[str, tuple[float, bool]] = {}
        self._ended: set[str] = set()
        self._shown = -math.inf
        self._lock = threading.Lock()

    def take(self, key: str, payload: bytes, now: float | None = None) -> None:
        """A report as received on ``key`` (``.../board/<sensor>``) at ``now``."""
        try:
            report = decode_board_report(payload)
        except WireFormatError:
            self._count("malformed")
            return
        if key.rsplit("/", 1)[-1] != report.sensor_id:
            self._count("wrong_key")
            return
        self.add(report, now)

    def add(self, report: BoardReport, now: float | None = None) -> None:
        """One report of a sensor, at ``now`` (default: its stamp)."""
        if report.sensor_id not in self.sensors:
            self._count("unknown")
            return
        if report.view is not None and not self._same_board(report.board):
            with self._lock:
                self.counts["other_board"] += 1
                self.other_board[report.sensor_id] = report.board  # type: ignore[assignment]
            report = replace(report, view=None)
        if (
            report.view is not None
            and self._views_of.get(report.sensor_id, 0) >= MAX_VIEWS_PER_SENSOR
        ):
            self._count("too_many_views")
            report = replace(report, view=None)
        with self._lock:
            self.counts["reports"] += 1
            sid = report.sensor_id
            if report.intrinsics is not None:
                self._intrinsics[sid] = report.intrinsics
            if report.view is not None:
                self._views.append(report.view)
                self.counts["views"] += 1
                self._views_of[sid] = self._views_of.get(sid, 0) + 1
            if report.end:
                self._ended.add(sid)
            now = report.stamp if now is None else now
            self._latest[sid] = (now, report.corners is not None)
            due = report.view is not None or now - self._shown >= self.every_s
            if due:
                self._shown = now
                seeing = self._seeing(now)
        if due and self.progress is not None:
            views = [] if report.view is None else [report.view]
            self.progress.observe(report.stamp, seeing, views)

    def _same_board(self, board: tuple[int, int, float] | None) -> bool:
        if self.board is None or board is None:
            return True
        return board[:2] == self.board[:2] and math.isclose(board[2], self.board[2], rel_tol=1e-6)

    def _count(self, what: str) -> None:
        with self._lock:
            self.counts[what] += 1

    def _seeing(self, now: float) -> list[str]:
        """Sensors whose latest report, at most ``SEEN_WITHIN_S`` old, found the board."""
        out = []
        for sid in self.sensors:
            latest = self._latest.get(sid)
            if latest is not None and latest[1] and abs(now - latest[0]) <= SEEN_WITHIN_S:
                out.append(sid)
        return out

    @property
    def reporting(self) -> set[str]:
        """The sensors that sent a report so far."""
        with self._lock:
            return set(self._latest)

    @property
    def views(self) -> list[BoardObservation]:
        """Every still view received so far."""
        with self._lock:
            return list(self._views)

    @property
    def intrinsics(self) -> dict[str, Intrinsics | None]:
        """Every sensor's camera model (``None`` for a sensor that sent none)."""
        with self._lock:
            return {sid: self._intrinsics.get(sid) for sid in self.sensors}

    @property
    def finished(self) -> bool:
        """Every sensor said its source ran out."""
        with self._lock:
            return self._ended >= set(self.sensors)
