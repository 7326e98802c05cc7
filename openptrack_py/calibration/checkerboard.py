"""Checkerboard views: the board's geometry, its corners in an image, its pose per view.

The calibration target of Munaro et al., OpenPTrack (§4) is a printed checkerboard moved
through the space. This module handles one sensor's view of it:

* :class:`Checkerboard` — the board: inner corners ``rows x cols``, square size, white
  margin; its object points in the **board frame** (origin at the first inner corner, x
  along a row of corners, y down the columns, z into the board, so that a camera facing
  the printed side sees x right and y down, as its own optical axes);
* :func:`detect_corners` — OpenCV's sector-based detector (``findChessboardCornersSB``,
  Duda & Frese, "Accurate Detection and Localization of Checkerboard Corners for
  Calibration") with the classic detector as a fallback, on the
  colour image or, for time-of-flight sensors (Kinect v2, SR4500), on the infrared image
  (:func:`detection_image`). Small images (the SR4500's 176 x 144) are searched again
  upscaled; corners are refined by ``cornerSubPix`` on the linear image, each with a
  window inside the squares around it. The corner order is made unique: right-handed
  as seen from the printed side, first corner next to the black corner square (a board
  with an odd and an even number of inner corners has a black square at one end of its
  diagonal and a white one at the other);
* :func:`board_pose` — the board's pose in the camera (``camera_from_board``) by
  ``solvePnP`` (IPPE, then Levenberg-Marquardt); :func:`detect_board` chains detection,
  undistortion (:func:`~openptrack_py.calibration.intrinsics.undistort_corners`) and
  pose; :func:`average_views` merges frames of a board lying still.

The optional pinhole and distortion estimate is in
:mod:`openptrack_py.calibration.intrinsics`. OpenCV is an optional dependency
(``pip install 'openptrack_py[sensor]'``): it is imported inside the functions that need
it (:func:`~openptrack_py.calibration.opencv.opencv`), never at module import, so the
board geometry is available without it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from openptrack_py.calibration.intrinsics import undistort_corners
from openptrack_py.calibration.opencv import opencv
from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.errors import CalibrationError, ConfigError
from openptrack_py.sensor_types import SENSOR_TYPES

UPSCALE_BELOW_PX = 300
"""Images smaller than this on a side are also searched upscaled (SR4500, 176 x 144)."""


@dataclass(frozen=True)
class Checkerboard:
    """A printed checkerboard target.

    Parameters
    ----------
    rows : int
        Inner corners along the board's y axis (down a column).
    cols : int
        Inner corners along the board's x axis (along a row).
    square_m : float
        Side of one square, metres.
    margin_m : float
        White margin around the outer squares, metres (detectors need one).

    Notes
    -----
    ``rows + cols`` must be odd: a board with an even and an odd count of inner corners
    has a black square at one end of its diagonal and a white one at the other, which
    makes the corner order (and so the board frame) unique. The square at negative x and
    y of the first corner is black.
    """

    rows: int = 5
    cols: int = 6
    square_m: float = 0.12
    margin_m: float = 0.08

    def __post_init__(self) -> None:
        if self.rows < 2 or self.cols < 2:
            raise ConfigError(
                f"checkerboard: rows and cols must be >= 2 (received {self.rows}x{self.cols})"
            )
        if (self.rows + self.cols) % 2 == 0:
            raise ConfigError(
                "checkerboard: one of rows and cols must be even and the other odd, else the "
                f"board's orientation is ambiguous (received {self.rows}x{self.cols})"
            )
        if not (math.isfinite(self.square_m) and self.square_m > 0):
            raise ConfigError(f"checkerboard.square_m: must be > 0 (received {self.square_m})")
        if not (math.isfinite(self.margin_m) and self.margin_m >= 0):
            raise ConfigError(f"checkerboard.margin_m: must be >= 0 (received {self.margin_m})")

    @classmethod
    def parse(cls, text: str) -> Checkerboard:
        """The board of ``ROWSxCOLSxSQUARE`` (inner corners, square side in metres).

        Raises
        ------
        ConfigError
            If the text is not of that form, or the board is not usable.
        """
        parts = text.lower().split("x")
        try:
            if len(parts) != 3:
                raise ValueError(text)
            rows, cols, square = int(parts[0]), int(parts[1]), float(parts[2])
        except ValueError:
            raise ConfigError(
                f"--board: expected ROWSxCOLSxSQUARE such as 5x6x0.12, got {text!r}"
            ) from None
        return cls(rows=rows, cols=cols, square_m=square)

    @property
    def spec(self) -> tuple[int, int, float]:
        """``(rows, cols, square_m)``: what a board report says of the board."""
        return self.rows, self.cols, self.square_m

    @property
    def corner_count(self) -> int:
        """Number of inner corners."""
        return self.rows * self.cols

    @property
    def pattern_size(self) -> tuple[int, int]:
        """OpenCV's ``patternSize``: ``(cols, rows)``."""
        return self.cols, self.rows

    def object_points(self) -> np.ndarray:
        """``(rows*cols, 3)`` inner corners in the board frame, row by row (OpenCV order)."""
        i, j = np.mgrid[0 : self.rows, 0 : self.cols]
        pts = np.zeros((self.corner_count, 3))
        pts[:, 0] = j.ravel() * self.square_m
        pts[:, 1] = i.ravel() * self.square_m
        return pts

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """The board's outline ``(x0, x1, y0, y1)`` in the board frame, margin included."""
        s, m = self.square_m, self.margin_m
        return -s - m, self.cols * s + m, -s - m, self.rows * s + m

    def outline(self) -> np.ndarray:
        """``(4, 3)`` corners of the board's outline in the board frame."""
        x0, x1, y0, y1 = self.extent
        return np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])

    @property
    def centre(self) -> np.ndarray:
        """Centre of the board in the board frame."""
        return np.array(
            [(self.cols - 1) * self.square_m / 2, (self.rows - 1) * self.square_m / 2, 0.0]
        )

    def is_black(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Whether board-frame points ``(x, y)`` lie on a black square."""
        s = self.square_m
        a = np.floor(np.asarray(y) / s) + 1  # square row, 0 .. rows
        b = np.floor(np.asarray(x) / s) + 1  # square column, 0 .. cols
        inside = (a >= 0) & (a <= self.rows) & (b >= 0) & (b <= self.cols)
        return inside & ((a + b) % 2 == 0)


@dataclass(frozen=True, eq=False)
class BoardView:
    """The board found in one image.

    Parameters
    ----------
    corners : ndarray
        ``(rows*cols, 2)`` pixel positions of the inner corners in the board's order
        (undistorted when distortion coefficients were given).
    camera_from_board : ndarray
        4x4 pose of the board in the camera's optical frame.
    rms_px : float
        Reprojection RMS of the pose, pixels.
    """

    corners: np.ndarray
    camera_from_board: np.ndarray
    rms_px: float


def uses_infrared(sensor_type: str) -> bool:
    """Whether the board is detected on the infrared image (time-of-flight sensors).

    Raises
    ------
    ConfigError
        For an unknown sensor type.
    """
    if sensor_type not in SENSOR_TYPES:
        raise ConfigError(
            f"sensor type: unknown {sensor_type!r} (allowed: {', '.join(SENSOR_TYPES)})"
        )
    return SENSOR_TYPES[sensor_type].time_of_flight


def detection_image(frame: Frame, sensor_type: str) -> np.ndarray:
    """The linear grey image the board is detected on, float32.

    The infrared (amplitude) image for time-of-flight sensors, else the colour image's
    luma. Linear, so that corner refinement sees the true saddle of each corner.

    Raises
    ------
    CalibrationError
        If the frame lacks the image the sensor type needs.
    """
    if uses_infrared(sensor_type):
        if frame.intensity is None:
            raise CalibrationError(f"checkerboard: a {sensor_type} frame needs an infrared image")
        return frame.intensity.astype(np.float32)
    if frame.color is None:
        raise CalibrationError(f"checkerboard: a {sensor_type} frame needs a colour image")
    rgb = frame.color.astype(np.float32)
    return rgb @ np.array([0.299, 0.587, 0.114], dtype=np.float32)


def to_8bit(image: np.ndarray) -> np.ndarray:
    """A grey image stretched to 8 bits between its 0.5 and 99.5 percentiles."""
    img = np.asarray(image, dtype=np.float32)
    lo, hi = np.percentile(img, [0.5, 99.5])
    scale = 255.0 / max(float(hi - lo), 1e-6)
    return np.clip((img - lo) * scale + 0.5, 0, 255).astype(np.uint8)


def _find(cv2: Any, img8: np.ndarray, board: Checkerboard) -> np.ndarray | None:
    """Corners by the sector-based detector, else the classic one; ``(n, 2)`` or None.

    Small images (below :data:`UPSCALE_BELOW_PX` pixels on a side) are tried again
    upscaled twice, where the sector-based detector finds squares of 5-6 pixels. The
    sector-based detector draws from OpenCV's global random generator: it is reseeded
    to OpenCV's initial state before each search, so that what is found in an image
    does not depend on the searches made before it in the process.
    """
    cv2.setRNGSeed(0)  # 0 is OpenCV's initial state (cv::RNG maps it to 0xffffffff)
    found, corners = cv2.findChessboardCornersSB(
        img8, board.pattern_size, flags=cv2.CALIB_CB_NORMALIZE_IMAGE
    )
    if found:
        return corners.reshape(-1, 2).astype(np.float64)
    if min(img8.shape) < UPSCALE_BELOW_PX:
        big = cv2.resize(img8, None, fx=2, fy=2, interpolation=cv2.INTER_CUBIC)
        cv2.setRNGSeed(0)
        found, corners = cv2.findChessboardCornersSB(
            big, board.pattern_size, flags=cv2.CALIB_CB_NORMALIZE_IMAGE
        )
        if found:  # OpenCV's resize maps pixel centres as x_big = 2 * x + 0.5
            return (corners.reshape(-1, 2).astype(np.float64) - 0.5) / 2
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FAST_CHECK
    found, corners = cv2.findChessboardCorners(img8, board.pattern_size, flags=flags)
    if found:
        return corners.reshape(-1, 2).astype(np.float64)
    return None


def _neighbour_spacing(corners: np.ndarray, board: Checkerboard) -> np.ndarray:
    """Per corner, the distance to its nearest grid neighbour, pixels."""
    grid = corners.reshape(board.rows, board.cols, 2)
    near = np.full((board.rows, board.cols), np.inf)
    along = np.linalg.norm(np.diff(grid, axis=1), axis=-1)
    down = np.linalg.norm(np.diff(grid, axis=0), axis=-1)
    near[:, :-1] = np.minimum(near[:, :-1], along)
    near[:, 1:] = np.minimum(near[:, 1:], along)
    near[:-1] = np.minimum(near[:-1], down)
    near[1:] = np.minimum(near[1:], down)
    return near.ravel()


def _refine(cv2: Any, image: np.ndarray, corners: np.ndarray, board: Checkerboard) -> np.ndarray:
    """``cornerSubPix`` on the linear image, each window within the squares around its corner.

    A corner's half-window is 0.4 of the distance to its nearest neighbour (2-6 pixels):
    on a foreshortened board a window sized for the whole board would reach the next
    corner and drag the corner off by pixels. A corner whose refinement moves by more
    than its half-window (hidden, or glare) keeps the detector's position.
    """
    halves = np.clip(np.round(0.4 * _neighbour_spacing(corners, board)), 2, 6).astype(int)
    lo, hi = np.percentile(image, [0.5, 99.5])
    norm = ((image - lo) / max(float(hi - lo), 1e-6)).astype(np.float32)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-5)
    refined = corners.copy()
    for half in np.unique(halves):
        idx = np.flatnonzero(halves == half)
        pts = corners[idx].astype(np.float32).reshape(-1, 1, 2).copy()
        cv2.cornerSubPix(norm, pts, (int(half), int(half)), (-1, -1), criteria)
        moved = pts.reshape(-1, 2).astype(np.float64)
        keep = np.linalg.norm(moved - corners[idx], axis=1) <= half
        refined[idx[keep]] = moved[keep]
    return refined


def _sample(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear samples of ``image`` at pixel positions ``uv`` (clamped to the image)."""
    h, w = image.shape
    u = np.clip(uv[:, 0], 0, w - 1.001)
    v = np.clip(uv[:, 1], 0, h - 1.001)
    u0, v0 = np.floor(u).astype(int), np.floor(v).astype(int)
    fu, fv = u - u0, v - v0
    top = image[v0, u0] * (1 - fu) + image[v0, u0 + 1] * fu
    bottom = image[v0 + 1, u0] * (1 - fu) + image[v0 + 1, u0 + 1] * fu
    return top * (1 - fv) + bottom * fv


def _orient(cv2: Any, image: np.ndarray, corners: np.ndarray, board: Checkerboard) -> np.ndarray:
    """The corners in the board's unique order (see :class:`Checkerboard`)."""
    grid = corners.reshape(board.rows, board.cols, 2)
    ex = grid[:, -1].mean(axis=0) - grid[:, 0].mean(axis=0)
    ey = grid[-1].mean(axis=0) - grid[0].mean(axis=0)
    if ex[0] * ey[1] - ex[1] * ey[0] < 0:  # mirrored: reverse each row
        grid = grid[:, ::-1]
    obj = board.object_points()[:, :2]
    homography, _ = cv2.findHomography(obj, grid.reshape(-1, 2), 0)
    s = board.square_m
    offsets = np.array([(a, b) for a in (-0.25, 0.0, 0.25) for b in (-0.25, 0.0, 0.25)]) * s
    first = np.array([-0.5 * s, -0.5 * s]) + offsets  # the black corner square
    last = np.array([(board.cols - 0.5) * s, (board.rows - 0.5) * s]) + offsets  # white

    def mean_at(points: np.ndarray) -> float:
        uv = cv2.perspectiveTransform(points.reshape(-1, 1, 2), homography).reshape(-1, 2)
        return float(_sample(image, uv).mean())

    if mean_at(first) > mean_at(last):  # rotated by 180 degrees
        grid = grid[::-1, ::-1]
    return grid.reshape(-1, 2).copy()


def detect_corners(
    image: np.ndarray,
    board: Checkerboard,
    *,
    refine: bool = True,
) -> np.ndarray | None:
    """The board's inner corners in a grey image, in the board's order.

    Parameters
    ----------
    image : ndarray
        ``(height, width)`` grey image, linear in scene radiance (see
        :func:`detection_image`); any dtype.
    board : Checkerboard
        The board to look for.
    refine : bool
        Refine corners with ``cornerSubPix`` on the linear image.

    Returns
    -------
    ndarray or None
        ``(rows*cols, 2)`` pixel positions (pixel centres at integer coordinates), or
        None when the whole board is not found.
    """
    cv2 = opencv()
    linear = np.asarray(image, dtype=np.float32)
    corners = _find(cv2, to_8bit(linear), board)
    if corners is None:
        return None
    corners = _orient(cv2, linear, corners, board)
    if refine:
        corners = _refine(cv2, linear, corners, board)
    return corners


def project(
    points: np.ndarray, camera_from_points: np.ndarray, intrinsics: Intrinsics
) -> np.ndarray:
    """Pinhole projection of ``(n, 3)`` points through a 4x4 pose, ``(n, 2)`` pixels."""
    cam = points @ camera_from_points[:3, :3].T + camera_from_points[:3, 3]
    k = intrinsics
    return np.column_stack(
        [k.fx * cam[:, 0] / cam[:, 2] + k.cx, k.fy * cam[:, 1] / cam[:, 2] + k.cy]
    )


def board_pose(corners: np.ndarray, board: Checkerboard, intrinsics: Intrinsics) -> BoardView:
    """The board's pose in the camera from undistorted corners.

    ``solvePnP`` with IPPE (the planar solver, which returns the better of the two
    planar-pose candidates), refined by Levenberg-Marquardt.

    Parameters
    ----------
    corners : ndarray
        ``(rows*cols, 2)`` undistorted pixel positions in the board's order.
    board : Checkerboard
        The board.
    intrinsics : Intrinsics
        The camera's pinhole model.

    Returns
    -------
    BoardView
        Corners, ``camera_from_board`` and the pose's reprojection RMS.

    Raises
    ------
    CalibrationError
        If OpenCV finds no pose.
    """
    cv2 = opencv()
    obj = board.object_points()
    img = np.asarray(corners, dtype=np.float64).reshape(-1, 1, 2)
    k = intrinsics.matrix
    ok, rvec, tvec = cv2.solvePnP(obj, img, k, None, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        raise CalibrationError("checkerboard: solvePnP found no pose for a detected board")
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, k, None, rvec, tvec)
    pose = np.eye(4)
    pose[:3, :3] = cv2.Rodrigues(rvec)[0]
    pose[:3, 3] = tvec.ravel()
    err = project(obj, pose, intrinsics) - img.reshape(-1, 2)
    rms = float(np.sqrt(np.mean(np.sum(err**2, axis=1))))
    return BoardView(np.asarray(corners, dtype=np.float64).reshape(-1, 2), pose, rms)


def detect_board(
    frame: Frame,
    board: Checkerboard,
    sensor_type: str,
    *,
    intrinsics: Intrinsics | None = None,
    distortion: np.ndarray | None = None,
    max_rms_px: float = 0.5,
) -> BoardView | None:
    """Find the board in a frame and its pose: detection, undistortion, ``solvePnP``.

    A detection whose corners do not fit a flat board's projection (pose RMS above
    ``max_rms_px``: corners misplaced on a foreshortened or partly hidden board) is
    dropped, as a calibration is better without it.

    Parameters
    ----------
    frame : Frame
        A capture with the image the sensor type is read on (see
        :func:`detection_image`).
    board : Checkerboard
        The board to look for.
    sensor_type : str
        ``kinect1``, ``kinect2``, ``realsense`` or ``sr4500``.
    intrinsics : Intrinsics, optional
        The camera model; the frame's when omitted.
    distortion : ndarray, optional
        OpenCV distortion coefficients ``(k1, k2, p1, p2[, k3])``; corners are returned
        undistorted.
    max_rms_px : float
        Largest reprojection RMS of the view's pose, pixels (raise it for cameras whose
        intrinsics are only nominal).

    Returns
    -------
    BoardView or None
        None when the whole board is not seen, or not well enough.

    Raises
    ------
    CalibrationError
        If the frame has no intrinsics and none are given, or lacks the needed image.
    """
    k = intrinsics or frame.intrinsics
    if k is None:
        raise CalibrationError("checkerboard: the frame has no intrinsics and none were given")
    corners = detect_corners(detection_image(frame, sensor_type), board)
    if corners is None:
        return None
    if distortion is None and k.has_lens:  # the camera model's own lens
        distortion = np.array(k.distortion)
    view = board_pose(undistort_corners(corners, k, distortion), board, k)
    return view if view.rms_px <= max_rms_px else None


def average_views(
    views: Sequence[BoardView], board: Checkerboard, intrinsics: Intrinsics
) -> BoardView:
    """One view of a board lying still from several frames: mean corners, pose again.

    Image noise is independent from frame to frame, so the mean of ``n`` frames'
    corners has ``sqrt(n)`` times less of it (the board must not move meanwhile, as
    when it lies on the floor).

    Raises
    ------
    CalibrationError
        With no views.
    """
    if not views:
        raise CalibrationError("checkerboard: no views to average")
    corners = np.mean([v.corners for v in views], axis=0)
    return board_pose(corners, board, intrinsics)
