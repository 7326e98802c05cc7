"""The floor: a plane in the camera's optical frame, estimated, calibrated or both.

A :class:`GroundPlane` is ``n . p + d = 0`` with ``|n| = 1`` and ``n`` pointing up (towards
the camera's side of the floor), so ``n . p + d`` is a point's height above the floor and
``d`` the camera's height.

:func:`estimate_ground` finds planes by RANSAC, keeps those whose normal lies within an
angle allowance of the expected up direction (Zhang et al., children behavior tracking,
Eq. 1; OpenPTrack keeps ``|n_y| >= 0.7``), and picks the lowest. :func:`choose_ground` is
OpenPTrack's rule for choosing between an estimated and a calibrated plane (Munaro et al.,
OpenPTrack, §5.1): keep the estimate while it is valid and close to calibration, else
calibration.
:class:`GroundTracker` holds the plane over time: found once, then locked or refined by a
least-squares fit of its inliers in every frame.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from openptrack_py.config import GroundConfig
from openptrack_py.errors import ConfigError


@dataclass(frozen=True, slots=True)
class GroundPlane:
    """A floor plane ``normal . p + offset = 0`` in the optical frame, normal pointing up.

    Parameters
    ----------
    normal : tuple of float
        Unit normal ``(a, b, c)``.
    offset : float
        ``d``: the camera's height above the plane, metres (positive when the camera is
        above it).
    source : str
        Where it came from: ``auto``, ``calibration``, ``fixed``.
    """

    normal: tuple[float, float, float]
    offset: float
    source: str = "auto"

    @classmethod
    def from_coefficients(
        cls, coefficients: tuple[float, float, float, float] | np.ndarray, source: str = "fixed"
    ) -> GroundPlane:
        """From ``a, b, c, d``, normalised and oriented so the camera is above it.

        Raises
        ------
        ConfigError
            If the coefficients are not finite or the normal is zero.
        """
        a, b, c, d = (float(v) for v in coefficients)
        norm = math.sqrt(a * a + b * b + c * c)
        if not all(math.isfinite(v) for v in (a, b, c, d)) or norm < 1e-9:
            raise ConfigError(
                f"ground plane: need finite a, b, c, d with a non-zero normal "
                f"(received {a}, {b}, {c}, {d})"
            )
        a, b, c, d = a / norm, b / norm, c / norm, d / norm
        if d < 0:  # the camera (origin) must be on the positive side
            a, b, c, d = -a, -b, -c, -d
        return cls((a, b, c), d, source)

    @classmethod
    def from_world_pose(cls, world_from_camera: np.ndarray) -> GroundPlane:
        """The world's floor ``z = 0`` seen from a camera at this pose."""
        rot = world_from_camera[:3, :3]
        normal = rot.T @ np.array([0.0, 0.0, 1.0])
        return cls(tuple(float(v) for v in normal), float(world_from_camera[2, 3]), "calibration")

    @property
    def coefficients(self) -> tuple[float, float, float, float]:
        """``a, b, c, d``."""
        return (*self.normal, self.offset)

    def height(self, points: np.ndarray) -> np.ndarray:
        """Signed height of optical-frame points above the plane."""
        return points @ np.asarray(self.normal, dtype=points.dtype) + self.offset

    def angle_to(self, other: GroundPlane) -> float:
        """Angle between the two normals, degrees."""
        cos = float(np.clip(np.dot(self.normal, other.normal), -1.0, 1.0))
        return math.degrees(math.acos(cos))

    def tilt_deg(self) -> float:
        """Downward tilt of the camera's optical axis relative to the floor."""
        return math.degrees(math.asin(float(np.clip(-self.normal[2], -1.0, 1.0))))

    def ground_from_camera(self) -> np.ndarray:
        """4x4 transform into a floor-aligned frame below the camera.

        Origin at the camera's foot on the floor, z up along the normal, x along the
        optical axis projected on the floor, y to the left.
        """
        n = np.asarray(self.normal)
        forward = np.array([0.0, 0.0, 1.0]) - n[2] * n
        if np.linalg.norm(forward) < 1e-6:  # looking straight down: use the image's up
            forward = np.array([0.0, -1.0, 0.0]) - (-n[1]) * n
        x = forward / np.linalg.norm(forward)
        y = np.cross(n, x)
        out = np.eye(4)
        out[:3, :3] = np.vstack([x, y, n])
        out[2, 3] = self.offset
        return out


def fit_plane(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares plane through points: unit normal and offset (``n . p + d = 0``)."""
    centre = points.mean(axis=0)
    cov = np.cov((points - centre).T)
    _, vecs = np.linalg.eigh(cov)
    normal = vecs[:, 0]
    return normal, -float(normal @ centre)


def _up_of_tilt(tilt_deg: float) -> np.ndarray:
    """World up in the optical frame of a camera pitched down by ``tilt_deg`` (no roll)."""
    tilt = math.radians(tilt_deg)
    return np.array([0.0, -math.cos(tilt), -math.sin(tilt)])


def _orient_up(normal: np.ndarray, offset: float) -> tuple[np.ndarray, float]:
    return (-normal, -offset) if offset < 0 else (normal, offset)


@dataclass(frozen=True, slots=True)
class PlaneCandidate:
    """A plane extracted by RANSAC, oriented with the camera above it.

    Parameters
    ----------
    normal : ndarray
        Unit normal, optical frame, pointing to the camera's side.
    offset : float
        The camera's distance to the plane, metres.
    inliers : int
        Points of the searched sample within the inlier distance.
    """

    normal: np.ndarray
    offset: float
    inliers: int

    def plane(self) -> GroundPlane:
        """As a :class:`GroundPlane` (source ``auto``)."""
        return GroundPlane(tuple(float(v) for v in self.normal), float(self.offset), "auto")


def extract_planes(
    points: np.ndarray,
    rng: np.random.Generator,
    *,
    inlier_m: float = 0.03,
    max_planes: int = 4,
    hypotheses: int = 200,
    sample: int = 6000,
    min_inlier_fraction: float = 0.04,
) -> list[PlaneCandidate]:
    """The largest planes of a cloud, one after another (each one's inliers removed).

    Parameters
    ----------
    points : ndarray
        ``(n, 3)`` finite optical-frame points.
    rng : numpy.random.Generator
        Sampling randomness.
    inlier_m : float
        Inlier distance.
    max_planes : int
        Planes extracted at most.
    hypotheses : int
        Random triples tried per plane.
    sample : int
        Points used for the search (a random subset).
    min_inlier_fraction : float
        A plane needs at least this share of the sample.
    """
    pts = np.asarray(points, dtype=np.float64)
    if len(pts) < 3:
        return []
    if len(pts) > sample:
        pts = pts[rng.choice(len(pts), sample, replace=False)]
    need = max(int(min_inlier_fraction * len(pts)), 30)
    found: list[PlaneCandidate] = []
    remaining = pts
    for _ in range(max_planes):
        if len(remaining) < need:
            break
        idx = rng.integers(0, len(remaining), size=(hypotheses, 3))
        a, b, c = remaining[idx[:, 0]], remaining[idx[:, 1]], remaining[idx[:, 2]]
        normals = np.cross(b - a, c - a)
        norms = np.linalg.norm(normals, axis=1)
        ok = norms > 1e-9
        if not ok.any():
            break
        normals = normals[ok] / norms[ok, None]
        offsets = -np.einsum("ij,ij->i", normals, a[ok])
        dist = np.abs(remaining @ normals.T + offsets)
        counts = (dist < inlier_m).sum(axis=0)
        best = int(np.argmax(counts))
        if counts[best] < need:
            break
        inliers = dist[:, best] < inlier_m
        normal, offset = fit_plane(remaining[inliers])
        inliers = np.abs(remaining @ normal + offset) < inlier_m
        normal, offset = _orient_up(*fit_plane(remaining[inliers]))
        found.append(PlaneCandidate(normal, float(offset), int(inliers.sum())))
        remaining = remaining[~inliers]
    return found


def lowest_within(
    candidates: list[PlaneCandidate], up: np.ndarray, allowance_deg: float
) -> PlaneCandidate | None:
    """The lowest candidate (farthest below the camera) whose normal is near ``up``."""
    up = np.asarray(up, dtype=float) / np.linalg.norm(up)
    cos_min = math.cos(math.radians(allowance_deg))
    near = [c for c in candidates if float(c.normal @ up) >= cos_min]
    return max(near, key=lambda c: c.offset) if near else None


def estimate_ground(
    points: np.ndarray,
    rng: np.random.Generator,
    *,
    expected_up: np.ndarray | None = None,
    angle_allowance_deg: float = 45.0,
    inlier_m: float = 0.03,
    max_planes: int = 4,
    hypotheses: int = 200,
    sample: int = 6000,
    min_inlier_fraction: float = 0.04,
) -> GroundPlane | None:
    """Find the floor in a cloud: the lowest plane whose normal is near the expected up.

    Parameters
    ----------
    points : ndarray
        ``(n, 3)`` finite optical-frame points.
    rng : numpy.random.Generator
        Sampling randomness.
    expected_up : ndarray, optional
        Expected floor normal (unit, optical frame); ``-y`` (an upright camera) if omitted.
    angle_allowance_deg : float
        Largest angle between a candidate's normal and ``expected_up``.
    inlier_m, max_planes, hypotheses, sample, min_inlier_fraction
        As :func:`extract_planes`.

    Returns
    -------
    GroundPlane or None
        None when no plane qualifies.
    """
    candidates = extract_planes(
        points, rng, inlier_m=inlier_m, max_planes=max_planes, hypotheses=hypotheses,
        sample=sample, min_inlier_fraction=min_inlier_fraction,
    )  # fmt: skip
    up = np.array([0.0, -1.0, 0.0]) if expected_up is None else np.asarray(expected_up, float)
    best = lowest_within(candidates, up, angle_allowance_deg)
    return None if best is None else best.plane()


DOWN_DOMINANCE = 1.5
"""With the tilt unknown, a floor for a camera looking (nearly) straight down is taken
over an upright camera's only when its plane holds this many times the points: a
ceiling sensor near a wall sees the wall as a plane an upright camera's floor could be
(the two worlds are 90-degree rotations of each other), but the floor under it is the
larger plane; a forward camera that sees more wall than floor still picks the floor."""


def choose_floor(candidates: list[PlaneCandidate], config: GroundConfig) -> GroundPlane | None:
    """The floor among extracted planes when the sensor's tilt is not known.

    Tries, in order, an upright camera (normal within 45 degrees of ``-y``, or the
    configured allowance if larger), a steep one (within 30 degrees of a 50-degree
    tilt) and one looking straight down (within 30 degrees of ``-z``); within each,
    the lowest plane. A straight-down floor replaces an upright or steep one only when it
    holds :data:`DOWN_DOMINANCE` times as many points.
    """
    upright = max(config.angle_allowance_deg, 45.0)
    tiers = [
        lowest_within(candidates, np.array([0.0, -1.0, 0.0]), upright),
        lowest_within(candidates, _up_of_tilt(GroundTracker.STEEP_TILT_DEG), 30.0),
    ]
    first = next((c for c in tiers if c is not None), None)
    down = lowest_within(candidates, np.array([0.0, 0.0, -1.0]), 30.0)
    if down is not None and (first is None or down.inliers >= DOWN_DOMINANCE * first.inliers):
        first = down
    return None if first is None else first.plane()


def choose_ground(
    estimated: GroundPlane | None,
    calibrated: GroundPlane | None,
    *,
    max_angle_diff_deg: float = 5.0,
    max_offset_diff_m: float = 0.15,
) -> GroundPlane | None:
    """OpenPTrack's rule: the estimate while valid and close to calibration, else calibration."""
    if calibrated is None:
        return estimated
    if estimated is None:
        return calibrated
    close = (
        estimated.angle_to(calibrated) <= max_angle_diff_deg
        and abs(estimated.offset - calibrated.offset) <= max_offset_diff_m
    )
    return estimated if close else calibrated


class GroundTracker:
    """The floor over time for one sensor.

    Parameters
    ----------
    config : GroundConfig
        Mode, lock, allowances.
    calibrated : GroundPlane, optional
        The floor from calibration (the sensor's pose), if known.
    rng : numpy.random.Generator, optional
        RANSAC randomness.

    Notes
    -----
    While no plane is found, the search is retried every :attr:`RETRY_FRAMES` frames;
    while calibration overrules the estimate, every :attr:`RECHECK_FRAMES`. Each search
    runs on the last ``accumulate_frames`` frames together (Munaro et al., OpenPTrack,
    §5.1): people walking over the floor hide different parts of it in each frame.
    """

    REFINE_SAMPLE = 8000
    """Points (evenly strided) used by each frame's refinement."""
    RETRY_FRAMES = 5
    RECHECK_FRAMES = 60

    def __init__(
        self,
        config: GroundConfig,
        calibrated: GroundPlane | None = None,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.config = config
        self.rng = rng or np.random.default_rng(0)
        if config.plane is not None:
            calibrated = GroundPlane.from_coefficients(config.plane, "fixed")
        self.calibrated = calibrated
        if config.mode == "calibration" and calibrated is None:
            raise ConfigError(
                "detector.ground.mode: 'calibration' needs a sensor pose or "
                "detector.ground.plane (allowed modes without one: auto)"
            )
        self.plane: GroundPlane | None = calibrated if config.mode == "calibration" else None
        self.estimates = 0
        self._since_estimate = 0
        self._recent: deque[np.ndarray] = deque(maxlen=config.accumulate_frames)

    def set_calibrated(self, calibrated: GroundPlane) -> None:
        """A new calibrated floor (the sensor's pose changed); a ``fixed`` plane stays."""
        if self.config.plane is not None:
            return
        self.calibrated = calibrated
        if self.config.mode == "calibration" or (self.plane and self.plane.source != "auto"):
            self.plane = calibrated
        self.estimates = 0  # look again, now with the new expected up

    STEEP_TILT_DEG = 50.0
    """With the tilt unknown, the second expected tilt tried (see :func:`choose_floor`)."""

    def _estimate(self) -> GroundPlane | None:
        """Search the accumulated frames for the floor."""
        cfg = self.config
        cloud = np.concatenate(list(self._recent)) if self._recent else np.empty((0, 3))
        candidates = extract_planes(cloud, self.rng, inlier_m=cfg.inlier_m)
        if self.calibrated is not None:
            best = lowest_within(
                candidates, np.asarray(self.calibrated.normal), cfg.angle_allowance_deg
            )
            return None if best is None else best.plane()
        if cfg.expected_tilt_deg is not None:
            best = lowest_within(
                candidates, _up_of_tilt(cfg.expected_tilt_deg), cfg.angle_allowance_deg
            )
            return None if best is None else best.plane()
        return choose_floor(candidates, cfg)

    def _remember(self, points: np.ndarray) -> None:
        """Keep a subsample of this frame for the search (:attr:`FRAME_SAMPLE` points)."""
        if len(points) > self.FRAME_SAMPLE:
            points = points[self.rng.choice(len(points), self.FRAME_SAMPLE, replace=False)]
        self._recent.append(np.asarray(points, dtype=np.float64))

    FRAME_SAMPLE = 3000
    """Points of each frame kept for the accumulated search."""

    def update(self, points: np.ndarray) -> GroundPlane | None:
        """The plane to use for this frame's optical-frame points (``None``: not found yet)."""
        cfg = self.config
        if cfg.mode == "calibration":
            return self.plane
        self._since_estimate += 1
        searching = self.plane is None or self.plane.source != "auto"
        if searching:
            self._remember(points)
        retry = self.RETRY_FRAMES if self.plane is None else self.RECHECK_FRAMES
        if searching and (self.estimates == 0 or self._since_estimate >= retry):
            self._since_estimate = 0
            estimate = self._estimate()
            self.estimates += 1
            chosen = (
                estimate
                if cfg.mode == "auto"
                else choose_ground(
                    estimate,
                    self.calibrated,
                    max_angle_diff_deg=cfg.max_angle_diff_deg,
                    max_offset_diff_m=cfg.max_offset_diff_m,
                )
            )
            self.plane = chosen
            return chosen
        if self.plane is None or self.plane.source != "auto":
            return self.plane
        if not cfg.lock and cfg.refine_rate > 0:
            self.plane = self._refine(self.plane, points)
        return self.plane

    def _refine(self, plane: GroundPlane, points: np.ndarray) -> GroundPlane:
        """Blend in a least-squares fit of this frame's inliers."""
        sample = points[:: max(1, len(points) // self.REFINE_SAMPLE)]
        inliers = sample[np.abs(plane.height(sample)) < self.config.inlier_m]
        if len(inliers) < 300:
            return plane
        normal, offset = _orient_up(*fit_plane(inliers.astype(np.float64)))
        fitted = GroundPlane(tuple(float(v) for v in normal), offset, "auto")
        if fitted.angle_to(plane) > 3.0 or abs(fitted.offset - plane.offset) > 0.1:
            return plane  # a big flat object in view, not the floor moving
        w = self.config.refine_rate
        blended = (1 - w) * np.asarray(plane.coefficients) + w * np.asarray(fitted.coefficients)
        out = GroundPlane.from_coefficients(blended, "auto")
        if self.calibrated is not None and self.config.mode == "both":
            return (
                choose_ground(
                    out,
                    self.calibrated,
                    max_angle_diff_deg=self.config.max_angle_diff_deg,
                    max_offset_diff_m=self.config.max_offset_diff_m,
                )
                or out
            )
        return out
