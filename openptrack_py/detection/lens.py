"""The lens model of a depth image: OpenCV's radial and tangential distortion.

Brown's model ("Decentering distortion of lenses", 1966) in the form and order OpenCV and
most calibration tools write it, ``(k1, k2, p1, p2, k3)``: a point ``(x, y)`` on the
normalised image plane (``x/z``, ``y/z``), at squared radius ``r2 = x^2 + y^2``, is imaged
at

    x' = x f + 2 p1 x y + p2 (r2 + 2 x^2)
    y' = y f + p1 (r2 + 2 y^2) + 2 p2 x y,   f = 1 + k1 r2 + k2 r2^2 + k3 r2^3.

A Kinect v2's factory depth lens (as its driver reports it) has all five terms, a
RealSense's the same five; most drivers deliver images already undistorted (all 0).

:func:`distort` images points, :func:`undistort` finds where a pixel looks (Newton's
method on the two equations, checked: where the model folds back on itself, which
strong fitted terms do inside the image, the pixel sees nothing and gets NaN), and
:func:`jacobian` is the model's 2x2 derivative that both use.
"""

from __future__ import annotations

import numpy as np

__all__ = ["LENS_TERMS", "distort", "jacobian", "undistort", "unfolded"]

LENS_TERMS = ("k1", "k2", "p1", "p2", "k3")
"""Names of the model's coefficients, in OpenCV's order."""

NEWTON_ITERATIONS = 12
"""Newton steps inverting the model (from the distorted point; 3-4 suffice for real lenses)."""


def _terms(coeffs: np.ndarray) -> tuple[np.ndarray, ...]:
    """The five coefficients of ``coeffs (..., 5)`` as separate arrays."""
    c = np.asarray(coeffs, dtype=float)
    return c[..., 0], c[..., 1], c[..., 2], c[..., 3], c[..., 4]


def distort(x: np.ndarray, y: np.ndarray, coeffs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the lens images normalised points ``(x, y)``.

    Parameters
    ----------
    x, y : ndarray
        Normalised image coordinates (``x/z``, ``y/z``) of the points.
    coeffs : ndarray
        ``(k1, k2, p1, p2, k3)``, shape ``(5,)`` or broadcastable with ``x`` on a last
        axis of 5 (one lens per point).

    Returns
    -------
    tuple of ndarray
        The distorted normalised coordinates ``x'``, ``y'``.
    """
    k1, k2, p1, p2, k3 = _terms(coeffs)
    r2 = x * x + y * y
    f = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xy = x * y
    return x * f + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x), y * f + p1 * (
        r2 + 2.0 * y * y
    ) + 2.0 * p2 * xy


def jacobian(x: np.ndarray, y: np.ndarray, coeffs: np.ndarray) -> tuple[np.ndarray, ...]:
    """The model's derivative at ``(x, y)``: ``d x'/dx, d x'/dy (= d y'/dx), d y'/dy``.

    The 2x2 matrix is symmetric. Its determinant is positive where the lens images a
    neighbourhood without folding it; for a radial lens it is ``f (f + 2 r2 f')``, whose
    second factor is the growth ``d (r f) / d r`` of the imaged radius.
    """
    k1, k2, p1, p2, k3 = _terms(coeffs)
    r2 = x * x + y * y
    f = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    df = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3)  # d f / d r2
    a = f + 2.0 * x * x * df + 2.0 * p1 * y + 6.0 * p2 * x
    b = 2.0 * x * y * df + 2.0 * p1 * x + 2.0 * p2 * y
    d = f + 2.0 * y * y * df + 6.0 * p1 * y + 2.0 * p2 * x
    return a, b, d


def unfolded(x: np.ndarray, y: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
    """Where the lens images normalised points ``(x, y)`` without folding (bool).

    Beyond the fold the model's image turns back towards the centre: a point there
    projects inside the image although no pixel sees it.
    """
    k1, k2, _, _, k3 = _terms(coeffs)
    r2 = x * x + y * y
    f = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    a, b, d = jacobian(x, y, coeffs)
    return (a * d - b * b > 0.0) & (f > 0.0)


def undistort(
    xd: np.ndarray, yd: np.ndarray, coeffs: np.ndarray, tolerance: float
) -> tuple[np.ndarray, np.ndarray]:
    """Where distorted normalised points ``(xd, yd)`` look, NaN where nothing is imaged there.

    Newton's method from the distorted point. A solution counts only if the model images
    it back within ``tolerance`` of the point and does not fold there (positive
    derivative determinant and radial factor): beyond the radius at which the imaged
    radius stops growing the model has a second, mirrored solution, and some points
    have none.

    Parameters
    ----------
    xd, yd : ndarray
        Distorted normalised coordinates.
    coeffs : ndarray
        ``(k1, k2, p1, p2, k3)``.
    tolerance : float
        Largest miss accepted, in normalised units.

    Returns
    -------
    tuple of ndarray
        Undistorted ``x``, ``y``; NaN where the model cannot be inverted.
    """
    xd = np.asarray(xd, dtype=float)
    yd = np.asarray(yd, dtype=float)
    x, y = xd.copy(), yd.copy()
    with np.errstate(all="ignore"):
        for _ in range(NEWTON_ITERATIONS):
            ex, ey = distort(x, y, coeffs)
            ex, ey = ex - xd, ey - yd
            a, b, d = jacobian(x, y, coeffs)
            det = a * d - b * b
            safe = np.where(np.abs(det) > 1e-12, det, np.nan)
            x = x - (d * ex - b * ey) / safe
            y = y - (a * ey - b * ex) / safe
        ex, ey = distort(x, y, coeffs)
        good = unfolded(x, y, coeffs) & (np.hypot(ex - xd, ey - yd) <= tolerance)
    return np.where(good, x, np.nan), np.where(good, y, np.nan)
