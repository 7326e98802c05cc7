"""What a depth source yields: a timestamped frame with its camera intrinsics.

Every source (rendered simulation, a folder of PNGs, a RealSense recording, a live device,
a point-cloud file) produces :class:`Frame` objects in the camera's **optical frame**:
x right, y down, z forward along the optical axis, metres. Depth images are organised
(``height x width``); clouds read from files may be unorganised, in which case the frame
carries ``points`` instead of ``depth``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from openptrack_py.detection.lens import LENS_TERMS, distort, undistort, unfolded
from openptrack_py.errors import ConfigError
from openptrack_py.sensor_types import SENSOR_TYPES

RAY_TOLERANCE_PX = 0.01
"""A ray whose distorted projection misses its pixel by more is not invertible there."""


@dataclass(frozen=True, slots=True)
class Intrinsics:
    """Camera model of a depth image: pinhole and lens distortion.

    Colour images are registered to the depth image.

    Parameters
    ----------
    width, height : int
        Image size, pixels.
    fx, fy : float
        Focal lengths, pixels.
    cx, cy : float
        Principal point, pixels.
    k1, k2 : float
        Radial lens distortion of the image (OpenCV's: a point at ``(x, y)`` on the
        normalised image plane is imaged at ``(x, y) (1 + k1 r^2 + k2 r^4 + k3 r^6)``
        plus the tangential terms); 0 for an image already undistorted, as most depth
        cameras' drivers deliver it.
    p1, p2 : float
        Tangential (decentering) distortion, OpenCV's (:mod:`openptrack_py.detection.lens`).
    k3 : float
        Third radial term. After ``p2`` in OpenCV's coefficient order, and last here so
        that the fields before it keep their positions.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    k3: float = 0.0

    def __post_init__(self) -> None:
        if self.width < 1 or self.height < 1:
            raise ConfigError(
                f"intrinsics: width and height must be >= 1 (received {self.width}x{self.height})"
            )
        for name in ("fx", "fy"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(
                    f"intrinsics.{name}: must be a positive number (received {value})"
                )
        for name in ("cx", "cy", *LENS_TERMS):
            if not math.isfinite(getattr(self, name)):
                raise ConfigError(f"intrinsics.{name}: must be finite")

    @classmethod
    def for_sensor(cls, sensor_type: str) -> Intrinsics:
        """Nominal intrinsics of a sensor type: kinect1, kinect2, realsense or sr4500.

        Image size and fields of view are those of
        :data:`openptrack_py.sensor_types.SENSOR_TYPES`.

        Raises
        ------
        ConfigError
            For an unknown type.
        """
        if sensor_type not in SENSOR_TYPES:
            raise ConfigError(
                f"sensor type: unknown {sensor_type!r} (allowed: {', '.join(SENSOR_TYPES)})"
            )
        kind = SENSOR_TYPES[sensor_type]
        return cls(kind.width, kind.height, *kind.intrinsics)

    @classmethod
    def from_matrix(cls, k: np.ndarray, width: int, height: int) -> Intrinsics:
        """From a 3x3 camera matrix."""
        k = np.asarray(k, dtype=float).reshape(3, 3)
        return cls(
            int(width), int(height), float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2])
        )

    @property
    def distortion(self) -> tuple[float, float, float, float, float]:
        """OpenCV's distortion coefficients ``(k1, k2, p1, p2, k3)``."""
        return (self.k1, self.k2, self.p1, self.p2, self.k3)

    @property
    def has_lens(self) -> bool:
        """Whether any distortion term is not 0 (else a plain pinhole)."""
        return any(self.distortion)

    def with_distortion(self, coeffs: tuple[float, ...] | np.ndarray) -> Intrinsics:
        """The same pinhole with OpenCV coefficients ``(k1, k2[, p1, p2[, k3]])``."""
        if len(coeffs) > len(LENS_TERMS):
            raise ConfigError(
                f"intrinsics.distortion: at most {len(LENS_TERMS)} terms "
                f"({', '.join(LENS_TERMS)}), received {len(coeffs)}"
            )
        terms = [float(c) for c in coeffs] + [0.0] * (len(LENS_TERMS) - len(coeffs))
        return Intrinsics(self.width, self.height, self.fx, self.fy, self.cx, self.cy, *terms)

    @property
    def matrix(self) -> np.ndarray:
        """The 3x3 camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def scaled(self, width: int, height: int) -> Intrinsics:
        """The same camera at another image size (with the same lens distortion)."""
        sx, sy = width / self.width, height / self.height
        return Intrinsics(
            width,
            height,
            self.fx * sx,
            self.fy * sy,
            (self.cx + 0.5) * sx - 0.5,
            (self.cy + 0.5) * sy - 0.5,
            *self.distortion,
        )

    def rays(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where pixels look: ``x/z`` and ``y/z`` of their rays, undistorted.

        The lens model is inverted by Newton's method
        (:func:`~openptrack_py.detection.lens.undistort`). Where it cannot be inverted
        (beyond the radius at which the imaged radius stops growing, which strong fitted
        terms put inside the image) no ray lands back on the pixel: those rays are NaN.

        Parameters
        ----------
        u, v : ndarray
            Pixel coordinates (column, row).

        Returns
        -------
        tuple of ndarray
            ``x/z`` and ``y/z`` per pixel, NaN where the lens cannot be inverted.
        """
        xd = (np.asarray(u, dtype=float) - self.cx) / self.fx
        yd = (np.asarray(v, dtype=float) - self.cy) / self.fy
        if not self.has_lens:
            return xd, yd
        tolerance = RAY_TOLERANCE_PX / max(self.fx, self.fy)
        return undistort(xd, yd, np.array(self.distortion), tolerance)

    def pixels(self, cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Image coordinates ``(u, v)`` of optical-frame points ``cam (..., 3)``.

        Through the lens; points at or behind the camera are not handled (clip ``z``
        first).
        """
        z = cam[..., 2]
        x, y = cam[..., 0] / z, cam[..., 1] / z
        if self.has_lens:
            x, y = distort(x, y, np.array(self.distortion))
        return self.fx * x + self.cx, self.fy * y + self.cy

    def to_dict(self) -> dict[str, float | int]:
        """Plain dict (for ``intrinsics.json``; the lens terms only when one is not 0)."""
        out: dict[str, float | int] = {
            "width": self.width,
            "height": self.height,
            "fx": self.fx,
            "fy": self.fy,
            "cx": self.cx,
            "cy": self.cy,
        }
        if self.has_lens:
            out.update(zip(LENS_TERMS, self.distortion, strict=True))
        return out

    @classmethod
    def from_dict(cls, data: dict) -> Intrinsics:
        """Inverse of :meth:`to_dict`.

        Raises
        ------
        ConfigError
            Naming a missing or invalid key.
        """
        try:
            return cls(
                int(data["width"]),
                int(data["height"]),
                float(data["fx"]),
                float(data["fy"]),
                float(data["cx"]),
                float(data["cy"]),
                *(float(data.get(name, 0.0)) for name in LENS_TERMS),
            )
        except KeyError as exc:
            raise ConfigError(
                f"intrinsics: missing key {exc.args[0]!r} (need width, height, fx, fy, cx, cy)"
            ) from None
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"intrinsics: {exc}") from None


@dataclass(frozen=True, slots=True, eq=False)
class Frame:
    """One capture of a depth sensor.

    Parameters
    ----------
    stamp : float
        Capture time, UNIX seconds (or seconds from the recording's start).
    seq : int
        Frame counter of the source.
    intrinsics : Intrinsics or None
        Camera model; ``None`` only for unorganised clouds.
    depth : ndarray or None
        ``(height, width)`` float32 depth in metres along the optical axis; NaN where
        invalid. Sources convert zeros and out-of-range codes to NaN.
    color : ndarray or None
        ``(height, width, 3)`` uint8 RGB registered to the depth image.
    intensity : ndarray or None
        ``(height, width)`` infrared (or amplitude) image, uint8 or uint16.
    points : ndarray or None
        ``(n, 3)`` float32 optical-frame points of an unorganised cloud (when ``depth`` is
        ``None``).
    point_colors : ndarray or None
        ``(n, 3)`` uint8 RGB of ``points``.
    """

    stamp: float
    seq: int
    intrinsics: Intrinsics | None
    depth: np.ndarray | None = None
    color: np.ndarray | None = None
    intensity: np.ndarray | None = None
    points: np.ndarray | None = None
    point_colors: np.ndarray | None = None

    @property
    def organised(self) -> bool:
        """Whether the frame is a depth image (else an unorganised cloud)."""
        return self.depth is not None


def image_box(cam: np.ndarray, k: Intrinsics, pad: int = 0) -> tuple[int, int, int, int] | None:
    """Pixel box ``(u0, u1, v0, v1)`` covering optical-frame points; None when out of view.

    The whole image when some point is at or behind the camera; ``pad`` more pixels on
    every side. Through a lens, straight edges bow: the midpoints of every pair of points
    are projected too, and 2 more pixels padded; and where a point lies beyond the lens's
    fold (where its projection turns back into the image) the box is the whole image.
    """
    z = cam[:, 2]
    if z.max() <= 0.05:
        return None
    if z.min() <= 0.05:
        return 0, k.width, 0, k.height
    if k.has_lens:
        i, j = np.triu_indices(len(cam), 1)
        pts = np.concatenate([cam, 0.5 * (cam[i] + cam[j])])
        if not unfolded(pts[:, 0] / pts[:, 2], pts[:, 1] / pts[:, 2], k.distortion).all():
            return 0, k.width, 0, k.height
        u, v = k.pixels(pts)
        pad += 2
    else:
        u = k.fx * cam[:, 0] / z + k.cx
        v = k.fy * cam[:, 1] / z + k.cy
    u0, u1 = max(math.floor(u.min()) - pad, 0), min(math.floor(u.max()) + 2 + pad, k.width)
    v0, v1 = max(math.floor(v.min()) - pad, 0), min(math.floor(v.max()) + 2 + pad, k.height)
    if u0 >= u1 or v0 >= v1:
        return None
    return u0, u1, v0, v1
