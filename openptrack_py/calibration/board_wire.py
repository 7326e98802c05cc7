"""What a sensor's machine says about the board during a live checkerboard session.

The live form of step 1 of the checkerboard calibration of Munaro et al., OpenPTrack
(§4): each sensor's machine finds the board in its own frames and publishes a compact
:class:`BoardReport` on ``opt/<site>/board/<sensor>`` (the images never leave it), and
the master gathers the reports into views and the progress display.

A report says, for one frame: where the board's inner corners are in the image (or that
it is not seen); the still view the frame completed, if any (a run of frames in which
the board was held still, its corners averaged and its pose in the camera, see
:class:`~openptrack_py.calibration.capture.StillBoardViews`); the sensor's intrinsics
(with its lens terms ``k1, k2, p1, p2, k3`` when one is not 0) and the board it looks for with
every completed view; and ``end`` when the sensor's
source ran out.

Wire form: one JSON object with the envelope of every message (``"v"``, ``"kind":
"board"``); :func:`decode_board_report` checks every field as strictly as the other
decoders and raises :class:`~openptrack_py.errors.WireFormatError` naming the first one
that is wrong.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from openptrack_py.calibration.observations import BoardObservation
from openptrack_py.detection.frame import Intrinsics
from openptrack_py.detection.lens import LENS_TERMS
from openptrack_py.errors import ConfigError, WireFormatError
from openptrack_py.messages.fields import (
    MAX_STAMP_S,
    SCHEMA_VERSION,
    check_keys,
    dump_message,
    fail,
    parse_message,
    read_bool,
    read_float,
    read_int,
    read_list,
    read_name,
)

__all__ = ["BoardReport", "decode_board_report", "encode_board_report"]

KIND = "board"
MAX_CORNERS = 1000
"""Most inner corners of a board (a 25 x 40 board is already unusually fine)."""
MAX_PIXELS = 100_000
"""Largest image side, pixels."""
MAX_VIEW_AGE_S = 60.0
"""A view is of a still run that ended with the report's frame: stamped within this."""
MAX_BOARD_DISTANCE_M = 100.0
"""No depth sensor sees a board farther away."""
_KEYS = frozenset(
    {"v", "kind", "sensor_id", "stamp", "corners", "view", "intrinsics", "board", "end"}
)
_VIEW_KEYS = frozenset({"stamp", "corners", "camera_from_board"})
_INTRINSIC_KEYS = frozenset({"width", "height", "fx", "fy", "cx", "cy", *LENS_TERMS})
MAX_LENS_TERM = 10.0
"""Largest lens distortion term a report may carry (real lenses: well under 1)."""


@dataclass(frozen=True)
class BoardReport:
    """One sensor's word on the board for one frame.

    Parameters
    ----------
    sensor_id : str
        The sensor.
    stamp : float
        The frame's capture time (the sensor's clock), seconds.
    corners : ndarray or None
        ``(n, 2)`` pixel positions of the board's inner corners in this frame, or
        ``None`` where the board was not found.
    view : BoardObservation or None
        The still view this frame completed, if any.
    intrinsics : Intrinsics or None
        The sensor's camera model (sent with every completed view).
    board : tuple of (int, int, float) or None
        The board the sensor looks for: inner corners (rows, columns) and square
        side in metres (sent with every completed view, so that a master expecting
        another board can refuse the view rather than solve at the wrong scale).
    end : bool
        The sensor's source ran out: no more reports will come.
    """

    sensor_id: str
    stamp: float
    corners: np.ndarray | None = None
    view: BoardObservation | None = None
    intrinsics: Intrinsics | None = None
    board: tuple[int, int, float] | None = None
    end: bool = False


def _points(value: np.ndarray, path: str) -> list[list[float]]:
    points = np.asarray(value, dtype=float)
    if points.ndim != 2 or points.shape[1] != 2 or not np.isfinite(points).all():
        raise WireFormatError(f"{path}: expected finite (n, 2) pixel positions")
    return points.tolist()


def encode_board_report(report: BoardReport) -> bytes:
    """Wire bytes of a report.

    Raises
    ------
    WireFormatError
        If a number is not finite or an array has the wrong shape.
    """
    obj: dict = {"v": SCHEMA_VERSION, "kind": KIND, "sensor_id": report.sensor_id,
                 "stamp": float(report.stamp)}  # fmt: skip
    if report.corners is not None:
        obj["corners"] = _points(report.corners, "corners")
    if report.view is not None:
        pose = np.asarray(report.view.camera_from_board, dtype=float)
        if pose.shape != (4, 4) or not np.isfinite(pose).all():
            raise WireFormatError("view.camera_from_board: expected a finite 4x4 matrix")
        obj["view"] = {
            "stamp": float(report.view.stamp),
            "corners": _points(report.view.corners, "view.corners"),
            "camera_from_board": pose.reshape(-1).tolist(),
        }
    if report.intrinsics is not None:
        k = report.intrinsics
        obj["intrinsics"] = {"width": k.width, "height": k.height, "fx": k.fx, "fy": k.fy,
                             "cx": k.cx, "cy": k.cy}  # fmt: skip
        if k.has_lens:  # the lens, when the camera reports one (optional on the wire)
            obj["intrinsics"].update(zip(LENS_TERMS, k.distortion, strict=True))
    if report.board is not None:
        rows, cols, square = report.board
        if not (math.isfinite(square) and square > 0):
            raise WireFormatError("board: the square side must be a positive number")
        obj["board"] = [int(rows), int(cols), float(square)]
    if report.end:
        obj["end"] = True
    return dump_message(obj)


def _read_points(obj: dict, key: str, path: str) -> np.ndarray:
    items = read_list(obj, key, path, MAX_CORNERS)
    if not items:
        raise WireFormatError(f"{path}{key}: expected at least one corner")
    for i, item in enumerate(items):
        if (
            type(item) is not list
            or len(item) != 2
            or any(type(c) not in (int, float) for c in item)
            or not all(-MAX_PIXELS <= c <= MAX_PIXELS for c in item)  # also refuses NaN
        ):
            raise fail(f"{path}{key}[{i}]", "a pixel position [u, v]", item)
    return np.asarray(items, dtype=float)


def _read_view(obj: dict, sensor_id: str, report_stamp: float) -> BoardObservation:
    check_keys(obj, _VIEW_KEYS, "view.")
    stamp = read_float(
        obj, "stamp", "view.", report_stamp - MAX_VIEW_AGE_S, report_stamp + MAX_VIEW_AGE_S
    )
    corners = _read_points(obj, "corners", "view.")
    values = read_list(obj, "camera_from_board", "view.", 16)
    if len(values) != 16 or any(type(c) not in (int, float) for c in values):
        raise fail("view.camera_from_board", "16 numbers (a 4x4 matrix by rows)", values)
    pose = np.asarray(values, dtype=float).reshape(4, 4)
    rotation = pose[:3, :3]
    if (
        not np.isfinite(pose).all()
        or not np.allclose(pose[3], [0.0, 0.0, 0.0, 1.0])
        or not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-6)
        or np.linalg.det(rotation) < 0
        or np.linalg.norm(pose[:3, 3]) > MAX_BOARD_DISTANCE_M
    ):
        raise fail("view.camera_from_board", "a rigid transform, the board in reach", values)
    return BoardObservation(sensor_id, stamp, corners, pose)


def _read_intrinsics(obj: dict) -> Intrinsics:
    check_keys(obj, _INTRINSIC_KEYS, "intrinsics.")
    try:
        return Intrinsics(
            width=read_int(obj, "width", "intrinsics.", 1, MAX_PIXELS),
            height=read_int(obj, "height", "intrinsics.", 1, MAX_PIXELS),
            fx=read_float(obj, "fx", "intrinsics."),
            fy=read_float(obj, "fy", "intrinsics."),
            cx=read_float(obj, "cx", "intrinsics."),
            cy=read_float(obj, "cy", "intrinsics."),
            **{name: _lens_term(obj, name) for name in LENS_TERMS},
        )
    except ConfigError as exc:
        raise WireFormatError(str(exc)) from None


def _lens_term(obj: dict, key: str) -> float:
    """An optional lens distortion term (0 when absent)."""
    if key not in obj:
        return 0.0
    return read_float(obj, key, "intrinsics.", -MAX_LENS_TERM, MAX_LENS_TERM)


def _read_board(obj: dict) -> tuple[int, int, float]:
    value = read_list(obj, "board", "", 3)
    if (
        len(value) != 3
        or any(type(n) is not int or not 2 <= n <= MAX_CORNERS for n in value[:2])
        or type(value[2]) not in (int, float)
        or not 0 < value[2] <= 10.0
    ):
        raise fail("board", "[rows, cols, square side in metres]", value)
    return int(value[0]), int(value[1]), float(value[2])


def decode_board_report(payload: bytes | bytearray | memoryview | str) -> BoardReport:
    """A report from wire bytes.

    Raises
    ------
    WireFormatError
        Naming the first field that is wrong.
    """
    obj = parse_message(payload, KIND, _KEYS)
    sensor_id = read_name(obj, "sensor_id", "")
    stamp = read_float(obj, "stamp", "", 0.0, MAX_STAMP_S)
    corners = _read_points(obj, "corners", "") if "corners" in obj else None
    board = _read_board(obj) if "board" in obj else None
    view = None
    if "view" in obj:
        if board is None:
            raise WireFormatError("board: missing (a view must say which board it is of)")
        view = _read_view(obj["view"], sensor_id, stamp)
    intrinsics = _read_intrinsics(obj["intrinsics"]) if "intrinsics" in obj else None
    if board is not None:
        corners_needed = board[0] * board[1]
        for path, points in (("corners", corners), ("view.corners", view and view.corners)):
            if points is not None and len(points) != corners_needed:
                raise WireFormatError(
                    f"{path}: {len(points)} corners, the board has {corners_needed}"
                )
    end = read_bool(obj, "end", "", default=False)
    return BoardReport(sensor_id, stamp, corners, view, intrinsics, board, end)
