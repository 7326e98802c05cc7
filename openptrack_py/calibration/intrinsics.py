"""A camera's own model from board views: pinhole and distortion, estimated and applied.

Optional in the checkerboard calibration of Munaro et al., OpenPTrack (§4), where each
sensor's factory intrinsics are usually used: :func:`calibrate_intrinsics` estimates
the pinhole and lens distortion from several views of the board by ``calibrateCamera``
(Zhang, "A Flexible New Technique for Camera Calibration"); :func:`undistort_corners`
moves detected corners to where an ideal pinhole would see them, as the pose solvers
(:mod:`openptrack_py.calibration.checkerboard`,
:mod:`openptrack_py.calibration.extrinsics`) expect, and :func:`distort_corners` moves
them back (a solve that refines the lens needs the corners as the camera saw them).

OpenCV is an optional dependency, imported only when a function here runs
(:func:`~openptrack_py.calibration.opencv.opencv`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from openptrack_py.calibration.opencv import opencv
from openptrack_py.detection.frame import Intrinsics
from openptrack_py.errors import CalibrationError

if TYPE_CHECKING:  # the board module uses undistort_corners: no import at run time
    from openptrack_py.calibration.checkerboard import Checkerboard

__all__ = ["IntrinsicCalibration", "calibrate_intrinsics", "distort_corners", "undistort_corners"]


def undistort_corners(
    corners: np.ndarray, intrinsics: Intrinsics, distortion: np.ndarray | None
) -> np.ndarray:
    """Corners moved to where an ideal pinhole with the same intrinsics would see them.

    Parameters
    ----------
    corners : ndarray
        ``(n, 2)`` raw (distorted) pixel positions.
    intrinsics : Intrinsics
        The camera's pinhole model.
    distortion : ndarray or None
        OpenCV coefficients ``(k1, k2, p1, p2[, k3])``; None or all zero for none.

    Returns
    -------
    ndarray
        ``(n, 2)`` undistorted pixel positions (the input, as float, without distortion).
    """
    if distortion is None or not np.any(distortion):
        return np.asarray(corners, dtype=np.float64)
    cv2 = opencv()
    k = intrinsics.matrix
    pts = np.asarray(corners, dtype=np.float64).reshape(-1, 1, 2)
    until = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)  # to the double
    dist = np.asarray(distortion, float)
    return cv2.undistortPointsIter(pts, k, dist, None, k, until).reshape(-1, 2)


def distort_corners(corners: np.ndarray, intrinsics: Intrinsics) -> np.ndarray:
    """Undistorted corners back where the camera's own lens images them.

    The inverse of :func:`undistort_corners` with the lens of ``intrinsics``: each
    corner's ray imaged through it (:meth:`~openptrack_py.detection.frame.Intrinsics.pixels`),
    so a round trip returns the raw corners to within 1e-9 px or so.

    Parameters
    ----------
    corners : ndarray
        ``(n, 2)`` undistorted pixel positions.
    intrinsics : Intrinsics
        The camera's pinhole and lens.

    Returns
    -------
    ndarray
        ``(n, 2)`` raw pixel positions (the input, as float, for a camera without a lens).
    """
    pts = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    if not intrinsics.has_lens:
        return pts
    k = intrinsics
    rays = np.stack([(pts[:, 0] - k.cx) / k.fx, (pts[:, 1] - k.cy) / k.fy, np.ones(len(pts))], 1)
    return np.stack(k.pixels(rays), axis=1)


@dataclass(frozen=True, eq=False)
class IntrinsicCalibration:
    """Pinhole and distortion estimated from board views.

    Parameters
    ----------
    intrinsics : Intrinsics
        Focal lengths and principal point.
    distortion : ndarray
        OpenCV coefficients ``(k1, k2, p1, p2, k3)``.
    rms_px : float
        ``calibrateCamera``'s reprojection RMS, pixels.
    views : int
        Board views used.
    """

    intrinsics: Intrinsics
    distortion: np.ndarray
    rms_px: float
    views: int


def calibrate_intrinsics(
    corner_sets: Sequence[np.ndarray],
    board: Checkerboard,
    width: int,
    height: int,
    *,
    initial: Intrinsics | None = None,
    distortion: bool = True,
) -> IntrinsicCalibration:
    """Intrinsics by ``cv2.calibrateCamera`` (Zhang's method) from several board views.

    Parameters
    ----------
    corner_sets : sequence of ndarray
        ``(rows*cols, 2)`` raw (distorted) corners per view.
    board : Checkerboard
        The board.
    width, height : int
        Image size, pixels.
    initial : Intrinsics, optional
        Starting camera matrix (e.g. the type's nominal intrinsics).
    distortion : bool
        Estimate ``k1, k2, p1, p2, k3``; else a distortion-free pinhole.

    Returns
    -------
    IntrinsicCalibration

    Raises
    ------
    CalibrationError
        With fewer than three views (Zhang's method needs at least three planes).
    """
    if len(corner_sets) < 3:
        raise CalibrationError(
            f"intrinsics: need at least 3 board views, received {len(corner_sets)}"
        )
    cv2 = opencv()
    obj = board.object_points().astype(np.float32)
    objects = [obj] * len(corner_sets)
    images = [np.asarray(c, dtype=np.float32).reshape(-1, 1, 2) for c in corner_sets]
    flags = 0
    k0 = None
    if initial is not None:
        flags |= cv2.CALIB_USE_INTRINSIC_GUESS
        k0 = initial.matrix
    if not distortion:
        flags |= (
            cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3
        )
    rms, k, dist, _, _ = cv2.calibrateCamera(
        objects, images, (width, height), k0, np.zeros(5), flags=flags
    )
    return IntrinsicCalibration(
        Intrinsics.from_matrix(k, width, height), np.asarray(dist, float).ravel()[:5],
        float(rms), len(corner_sets),
    )  # fmt: skip
