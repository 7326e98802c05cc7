"""Board views from a sensor's stream of frames: what a recorded or live session gives.

Step 1 of the checkerboard calibration of Munaro et al., OpenPTrack (§4), on real
streams: the board is moved through the space and held still at each placement while
the sensors capture it. The sensors are not synchronised, so a view is only usable while
the board is still: :class:`StillBoardViews` finds the board in each frame
(:func:`~openptrack_py.calibration.checkerboard.detect_board`), follows runs of frames in
which its corners stay within ``still_px`` of the run's first, and turns each run of at
least ``min_frames`` frames into one view at the run's middle stamp, its corners
averaged (:func:`~openptrack_py.calibration.checkerboard.average_views`: image noise
falls as the square root of the frames). A moving board, a board seen in too few frames
and a frame whose board was not found end a run. :meth:`StillBoardViews.report` says
the same as a :class:`~openptrack_py.calibration.board_wire.BoardReport`, what a
sensor's machine publishes during a live session.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from openptrack_py.calibration.board_wire import BoardReport
from openptrack_py.calibration.checkerboard import (
    BoardView,
    Checkerboard,
    average_views,
    detect_board,
)
from openptrack_py.calibration.observations import BoardObservation
from openptrack_py.detection.frame import Frame, Intrinsics

__all__ = ["StillBoardViews", "board_observations"]


@dataclass
class StillBoardViews:
    """Turns one sensor's frames into views of the board held still.

    Parameters
    ----------
    sensor_id : str
        The sensor.
    sensor_type : str
        Its type (which image the board is found on).
    board : Checkerboard
        The board.
    still_px : float
        Largest corner movement from the run's first frame, pixels.
    min_frames : int
        Fewest frames of one still run.
    max_gap_s : float
        A longer gap between two frames ends a run.
    hold_s : float
        A run still this long gives its view at once (a live camera's last placement,
        the board lying on the floor, never ends by moving); the rest of the run adds
        nothing.
    """

    sensor_id: str
    sensor_type: str
    board: Checkerboard
    still_px: float = 1.0
    min_frames: int = 3
    max_gap_s: float = 0.25
    hold_s: float = 1.0
    frames: int = 0
    found: int = 0
    _run: list[tuple[float, BoardView]] = field(default_factory=list)
    _intrinsics: Intrinsics | None = None
    _given: bool = False  # the current run's view was given already
    _last_t: float = 0.0  # the current run's latest frame

    def add(self, frame: Frame) -> tuple[BoardObservation | None, BoardView | None]:
        """Take the next frame; return a view the frame completed (if any) and its own.

        The first is the still run the frame ended (a :class:`BoardObservation`), the
        second what was found in this frame (``None`` if no board), for a progress view.
        """
        self.frames += 1
        self._intrinsics = frame.intrinsics or self._intrinsics
        view = detect_board(frame, self.board, self.sensor_type)
        done = None
        if view is None:
            done = self.flush()
            return done, None
        self.found += 1
        if self._run and not self._continues(frame.stamp, view):
            done = self.flush()
        self._last_t = frame.stamp
        if self._given:  # still the same placement, already given
            return done, view
        self._run.append((frame.stamp, view))
        if done is None and frame.stamp - self._run[0][0] >= self.hold_s:
            done = self._view_of(self._run)
            self._given = done is not None
        return done, view

    def _continues(self, stamp: float, view: BoardView) -> bool:
        first = self._run[0][1]
        moved = float(np.abs(view.corners - first.corners).max())
        return moved <= self.still_px and stamp - self._last_t <= self.max_gap_s

    def report(self, frame: Frame) -> BoardReport:
        """Take the next frame; what the sensor says of it (see :meth:`add`)."""
        done, view = self.add(frame)
        return BoardReport(
            self.sensor_id,
            frame.stamp,
            corners=None if view is None else view.corners,
            view=done,
            intrinsics=None if done is None else self._intrinsics,
            board=None if done is None else self.board.spec,
        )

    def end_report(self, stamp: float) -> BoardReport:
        """The last report, once the frames ran out: the run in progress, if long enough."""
        return BoardReport(
            self.sensor_id, stamp, view=self.flush(), intrinsics=self._intrinsics,
            board=self.board.spec, end=True,
        )  # fmt: skip

    @property
    def intrinsics(self) -> Intrinsics | None:
        """The sensor's camera model, from its frames (``None`` before any frame had one)."""
        return self._intrinsics

    def flush(self) -> BoardObservation | None:
        """End the current run: its view if it was long enough (and not given yet)."""
        run, self._run = self._run, []
        given, self._given = self._given, False
        return None if given else self._view_of(run)

    def _view_of(self, run: list[tuple[float, BoardView]]) -> BoardObservation | None:
        """The view of a still run: corners averaged, stamped at the run's middle."""
        if len(run) < self.min_frames or self._intrinsics is None:
            return None
        view = average_views([v for _, v in run], self.board, self._intrinsics)
        stamps = [t for t, _ in run]
        stamp = 0.5 * (stamps[0] + stamps[-1])
        return BoardObservation(self.sensor_id, stamp, view.corners, view.camera_from_board)


def board_observations(
    frames: Iterable[Frame],
    sensor_id: str,
    sensor_type: str,
    board: Checkerboard,
    **options: float,
) -> tuple[list[BoardObservation], Intrinsics | None]:
    """Every still view of the board in one sensor's frames, and the sensor's intrinsics.

    ``options`` are :class:`StillBoardViews`'s ``still_px``, ``min_frames``, ``max_gap_s``.
    """
    views = StillBoardViews(sensor_id, sensor_type, board, **options)  # type: ignore[arg-type]
    out = []
    for frame in frames:
        done, _ = views.add(frame)
        if done is not None:
            out.append(done)
    last = views.flush()
    if last is not None:
        out.append(last)
    return out, views.intrinsics
