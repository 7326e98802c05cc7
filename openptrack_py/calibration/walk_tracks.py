"""One sensor's side of the walk: floor poses, its detections, the walker's trajectory.

Its single role is everything that concerns one sensor on its own, before any pairing
(Zhang et al., children behavior tracking, §2.2, and Munaro et al., OpenPTrack, §4.3,
both calibrate from one person's positions over time):

* :class:`Pose2D`, a sensor's floor frame in the world (``x``, ``y``, ``yaw``);
* :class:`WalkTrack`, its detections during the walk, with :func:`tracks_from_batches`
  (recorded detection batches grouped by sensor) and :func:`report_in_world`
  (floor-frame tracks as calibrated sensors would publish them);
* the walker in those detections: detections linked into tracklets stamp by stamp,
  static and short-lived tracklets (clutter, decoys, split blobs) dropped, one
  detection per stamp kept, and a robust local quadratic fit for smoothed positions
  and velocities;
* time matching: the trajectory interpolated at another sensor's stamps (smoothed for
  the solve, raw detections for the disagreement), only between samples of one
  tracklet close enough in time.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from openptrack_py.calibration.walk_settings import WalkSettings
from openptrack_py.detection.ground import GroundPlane
from openptrack_py.errors import CalibrationError
from openptrack_py.geometry import invert

if TYPE_CHECKING:
    from openptrack_py.config import Pose
    from openptrack_py.messages.detection import DetectionBatch

__all__ = [
    "Pose2D",
    "WalkTrack",
    "floor_from_world",
    "report_in_world",
    "tracks_from_batches",
]


def _wrap_deg(angle: float) -> float:
    """``angle`` in degrees, wrapped to ``(-180, 180]``."""
    wrapped = math.fmod(angle + 180.0, 360.0)
    if wrapped <= 0.0:
        wrapped += 360.0
    return wrapped - 180.0


def _rot(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


# ------------------------------------------------------------------------------- data


@dataclass(frozen=True)
class Pose2D:
    """A rigid transform of the floor: a sensor's floor frame in the world.

    ``world = R(yaw) @ floor + (x, y)``. For a sensor with the world
    :class:`~openptrack_py.config.Pose` ``(x, y, z, yaw, pitch, roll)`` its floor pose is
    ``(x, y, yaw)``: the floor frame's origin is the camera's foot and its ``x`` axis the
    optical axis projected on the floor, which roll about that axis does not move.

    Parameters
    ----------
    x, y : float
        The floor frame's origin in the world, metres.
    yaw_deg : float
        Its heading, degrees counter-clockwise from the world's ``+x``.
    """

    x: float = 0.0
    y: float = 0.0
    yaw_deg: float = 0.0

    @classmethod
    def from_pose(cls, pose: Pose) -> Pose2D:
        """The floor pose of a sensor's 3-D world pose (drops height, tilt and roll)."""
        return cls(float(pose.x), float(pose.y), float(pose.yaw_deg))

    def to_pose(self, base: Pose) -> Pose:
        """``base`` with its position on the floor and heading replaced by this pose's."""
        return base.model_copy(update={"x": self.x, "y": self.y, "yaw_deg": self.yaw_deg})

    @property
    def yaw(self) -> float:
        """Heading, radians."""
        return math.radians(self.yaw_deg)

    def rotation(self) -> np.ndarray:
        """The 2x2 rotation."""
        return _rot(self.yaw)

    def as_matrix(self) -> np.ndarray:
        """The 3x3 homogeneous matrix."""
        out = np.eye(3)
        out[:2, :2] = self.rotation()
        out[:2, 2] = (self.x, self.y)
        return out

    def apply(self, xy: np.ndarray) -> np.ndarray:
        """Map ``(n, 2)`` floor-frame points to the world."""
        pts = np.asarray(xy, dtype=float).reshape(-1, 2)
        return pts @ self.rotation().T + np.array([self.x, self.y])

    def inverse(self) -> Pose2D:
        """The world in this frame."""
        back = -self.rotation().T @ np.array([self.x, self.y])
        return Pose2D(float(back[0]), float(back[1]), _wrap_deg(-self.yaw_deg))

    def compose(self, other: Pose2D) -> Pose2D:
        """``self ∘ other``: first ``other``, then ``self``."""
        t = self.rotation() @ np.array([other.x, other.y]) + np.array([self.x, self.y])
        return Pose2D(float(t[0]), float(t[1]), _wrap_deg(self.yaw_deg + other.yaw_deg))

    def error_to(self, other: Pose2D) -> tuple[float, float]:
        """Position (metres) and absolute heading (degrees) difference to ``other``."""
        return (
            math.hypot(self.x - other.x, self.y - other.y),
            abs(_wrap_deg(self.yaw_deg - other.yaw_deg)),
        )


def _readonly(values: np.ndarray) -> np.ndarray:
    values.setflags(write=False)
    return values


@dataclass(frozen=True, eq=False)
class WalkTrack:
    """One sensor's detections during the walk.

    Every detection the sensor reported, the walker's and anything else's (clutter,
    decoys, split blobs); several per stamp are allowed, missed frames simply have none.

    Parameters
    ----------
    sensor_id : str
        The sensor.
    stamps : ndarray
        ``(n,)`` stamps on the sensor's clock, seconds (UNIX or any common origin).
    xy : ndarray
        ``(n, 2)`` positions on the floor, metres: in the sensor's floor frame, or in the
        world through its current pose (see :func:`refine_walk`).
    confidence : ndarray, optional
        ``(n,)`` detector confidences on ``[0, 1]``; 1 for all if omitted.

    Raises
    ------
    CalibrationError
        If the arrays disagree in length or hold non-finite values.
    """

    sensor_id: str
    stamps: np.ndarray
    xy: np.ndarray
    confidence: np.ndarray | None = None

    def __post_init__(self) -> None:
        stamps = np.asarray(self.stamps, dtype=float).reshape(-1)
        xy = np.asarray(self.xy, dtype=float)
        if xy.size == 0:
            xy = xy.reshape(0, 2)
        conf = (
            np.ones(len(stamps))
            if self.confidence is None
            else np.asarray(self.confidence, dtype=float).reshape(-1)
        )
        where = f"walk track {self.sensor_id!r}"
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise CalibrationError(f"{where}: xy must be (n, 2) (received shape {xy.shape})")
        if not (len(stamps) == len(xy) == len(conf)):
            raise CalibrationError(
                f"{where}: stamps, xy and confidence differ in length "
                f"({len(stamps)}, {len(xy)}, {len(conf)})"
            )
        if not (np.isfinite(stamps).all() and np.isfinite(xy).all() and np.isfinite(conf).all()):
            raise CalibrationError(f"{where}: stamps, xy and confidence must be finite")
        order = np.argsort(stamps, kind="stable")
        object.__setattr__(self, "stamps", _readonly(stamps[order].copy()))
        object.__setattr__(self, "xy", _readonly(xy[order].copy()))
        object.__setattr__(self, "confidence", _readonly(conf[order].copy()))

    def __len__(self) -> int:
        return len(self.stamps)

    def transformed(self, pose: Pose2D) -> WalkTrack:
        """The same detections with ``pose`` applied to their positions."""
        return WalkTrack(self.sensor_id, self.stamps, pose.apply(self.xy), self.confidence)


def tracks_from_batches(
    batches: Iterable[DetectionBatch], believed: Mapping[str, np.ndarray] | None = None
) -> tuple[WalkTrack, ...]:
    """Group detection batches (as recorded from the network) into one track per sensor.

    Parameters
    ----------
    batches : iterable of DetectionBatch
        Every batch received during the walk, any order, any sensors.
    believed : mapping, optional
        Each sensor's ``world_from_optical`` (4x4) as its detector believed it while
        recording. With it every track is in its sensor's floor frame: a batch in the
        sensor's own frame (``frame_id`` its id: a detector without a pose) is already,
        a batch in ``world`` is taken back through the believed pose
        (:func:`floor_from_world`). Without it positions are the batches' ``x, y``.

    Returns
    -------
    tuple of WalkTrack
        One per sensor, in the order sensors first appear.

    Raises
    ------
    CalibrationError
        With ``believed``: a ``world`` batch of a sensor with no believed pose, or a
        batch in another frame, naming the sensor.
    """
    rows: dict[str, list[np.ndarray]] = {}
    to_floor: dict[str, np.ndarray | None] = {}
    for batch in batches:
        sensor = batch.sensor_id
        target = rows.setdefault(sensor, [])
        if not batch.detections:
            continue
        values = np.array(
            [(batch.stamp, d.x, d.y, d.z, d.confidence) for d in batch.detections], dtype=float
        )
        if believed is not None and batch.frame_id != sensor:
            if batch.frame_id != "world":
                raise CalibrationError(
                    f"walk: sensor {sensor!r} reported in frame {batch.frame_id!r} "
                    f"(expected 'world' or its own frame {sensor!r})"
                )
            if sensor not in to_floor:
                if sensor not in believed:
                    raise CalibrationError(
                        f"walk: sensor {sensor!r} reported in the world frame but the network "
                        "gives it no pose to take its detections back to its floor"
                    )
                to_floor[sensor] = floor_from_world(believed[sensor])
            tf = to_floor[sensor]
            values[:, 1:4] = values[:, 1:4] @ tf[:3, :3].T + tf[:3, 3]
        target.append(values)
    out = []
    for sensor, chunks in rows.items():
        arr = np.concatenate(chunks) if chunks else np.zeros((0, 5))
        order = np.argsort(arr[:, 0], kind="stable")
        arr = arr[order]
        out.append(WalkTrack(sensor, arr[:, 0], arr[:, 1:3], arr[:, 4]))
    return tuple(out)


def floor_from_world(world_from_camera: np.ndarray) -> np.ndarray:
    """4x4 transform from world positions reported through a pose to that sensor's floor.

    A detector maps what it sees to the world with the pose it believes
    (``world_from_camera``, optical frame); undoing that pose gives the optical frame, and
    the floor plane seen from it (the same for the true and a believed pose that differ
    on the floor only) gives the sensor's floor frame
    (:meth:`~openptrack_py.detection.ground.GroundPlane.ground_from_camera`).
    """
    ground = GroundPlane.from_world_pose(world_from_camera).ground_from_camera()
    return ground @ invert(world_from_camera)


def report_in_world(
    tracks: Sequence[WalkTrack], poses: Mapping[str, Pose2D]
) -> tuple[WalkTrack, ...]:
    """Floor-frame tracks as sensors calibrated with ``poses`` would report them.

    Raises
    ------
    CalibrationError
        If a track's sensor has no pose.
    """
    missing = [t.sensor_id for t in tracks if t.sensor_id not in poses]
    if missing:
        raise CalibrationError(f"walk: no pose for sensor {', '.join(missing)}")
    return tuple(t.transformed(poses[t.sensor_id]) for t in tracks)


# ------------------------------------------------------------------ one sensor's walker


@dataclass(frozen=True, eq=False)
class _Walker:
    """One sensor's walker trajectory: at most one detection per stamp.

    ``t`` is on the sensor's clock, minus the session origin; ``seg`` labels the
    tracklet each sample comes from; ``smooth`` and ``vel`` are the local quadratic
    fit's position and velocity; ``link[k]`` says whether samples ``k`` and ``k + 1`` may
    be interpolated between.
    """

    sensor: str
    t: np.ndarray
    xy: np.ndarray
    seg: np.ndarray
    smooth: np.ndarray
    vel: np.ndarray
    link: np.ndarray
    detections: int


def _tracklets(t: np.ndarray, xy: np.ndarray, s: WalkSettings) -> np.ndarray:
    """Label each detection with a tracklet (greedy nearest-neighbour linking per stamp)."""
    labels = np.full(len(t), -1, dtype=int)
    starts = np.flatnonzero(np.r_[True, np.diff(t) > 0])
    ends = np.r_[starts[1:], len(t)]
    last_t: list[float] = []
    last_xy: list[np.ndarray] = []
    alive: list[int] = []
    for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
        now = float(t[a])
        alive = [k for k in alive if now - last_t[k] <= s.max_gap_s]
        pairs: list[tuple[float, int, int]] = []
        for k in alive:
            gate = s.link_gate_m + s.max_speed_m_s * (now - last_t[k])
            dist = np.linalg.norm(xy[a:b] - last_xy[k], axis=1)
            pairs += [(float(d), k, a + c) for c, d in enumerate(dist.tolist()) if d <= gate]
        pairs.sort()
        used_tracks: set[int] = set()
        for _, k, row in pairs:
            if k in used_tracks or labels[row] >= 0:
                continue
            labels[row] = k
            used_tracks.add(k)
            last_t[k], last_xy[k] = now, xy[row]
        for row in range(a, b):
            if labels[row] < 0:
                labels[row] = len(last_t)
                alive.append(len(last_t))
                last_t.append(now)
                last_xy.append(xy[row])
    return labels


def _smooth(
    t: np.ndarray, xy: np.ndarray, seg: np.ndarray, half: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Robust local quadratic fit per segment: positions, velocities, support mask.

    A running median of five samples first removes single-frame outliers; then each
    sample's position and velocity come from a tricube-weighted quadratic in time over
    ``±half`` seconds of its own segment.
    """
    n = len(t)
    if n == 0:
        return xy.copy(), np.zeros_like(xy), np.zeros(0, dtype=bool)
    idx = np.clip(np.arange(n)[:, None] + np.arange(-2, 3)[None, :], 0, n - 1)
    same = seg[idx] == seg[:, None]
    med = np.stack(
        [np.nanmedian(np.where(same, xy[idx, c], np.nan), axis=1) for c in range(2)], axis=1
    )
    step = float(np.median(np.diff(t))) if n > 1 else half
    reach = int(min(max(math.ceil(half / max(step, 1e-3) * 1.5), 3), 80))
    idx = np.clip(np.arange(n)[:, None] + np.arange(-reach, reach + 1)[None, :], 0, n - 1)
    u = (t[idx] - t[:, None]) / half
    w = np.clip(1.0 - np.abs(u) ** 3, 0.0, None) ** 3
    w = np.where((seg[idx] == seg[:, None]) & (np.abs(u) < 1.0), w, 0.0)
    # the clip above repeats edge samples: count each neighbour once
    dup = np.zeros_like(w, dtype=bool)
    dup[:, 1:] = idx[:, 1:] == idx[:, :-1]
    w[dup] = 0.0
    basis = np.stack([np.ones_like(u), u, u * u], axis=2)  # (n, m, 3)
    gram = np.einsum("nm,nmi,nmj->nij", w, basis, basis) + 1e-6 * np.eye(3)
    rhs = np.einsum("nm,nmi,nmc->nic", w, basis, med[idx])
    support = (w > 0).sum(axis=1)
    side = (np.where(w > 0, u, 0.0) > 0).any(axis=1) & (np.where(w > 0, u, 0.0) < 0).any(axis=1)
    ok = (support >= 5) & side
    coef = np.linalg.solve(gram, rhs)  # (n, 3, 2)
    smooth = np.where(ok[:, None], coef[:, 0, :], med)
    vel = np.where(ok[:, None], coef[:, 1, :] / half, 0.0)
    return smooth, vel, ok


def _walker(track: WalkTrack, origin: float, s: WalkSettings) -> _Walker:
    """The walker's trajectory in one sensor's detections.

    Raises
    ------
    CalibrationError
        If fewer than ``min_detections`` detections, or of them, follow a walker.
    """
    sid = track.sensor_id
    keep = track.confidence >= s.min_confidence  # type: ignore[operator]
    total = int(keep.sum())
    if total < s.min_detections:
        raise CalibrationError(
            f"sensor {sid}: {total} detections during the walk (need at least "
            f"{s.min_detections}); the walker must cross its view"
        )
    t = track.stamps[keep] - origin
    xy = track.xy[keep]
    labels = _tracklets(t, xy, s)
    count = np.bincount(labels)
    good = np.zeros(len(count), dtype=bool)
    for k in np.flatnonzero(count >= s.min_tracklet_points).tolist():
        rows = labels == k
        span = float(t[rows][-1] - t[rows][0])
        pts = xy[rows]
        motion = float(np.max(np.linalg.norm(pts - np.median(pts, axis=0), axis=1)))
        good[k] = span >= s.min_tracklet_s and motion >= s.min_tracklet_motion_m
    score = np.where(good, count, -1)[labels]
    # one detection per stamp: the one of the best (longest) kept tracklet
    order = np.lexsort((-score, t))
    first = np.r_[True, np.diff(t[order]) > 0]
    chosen = order[first]
    chosen = chosen[score[chosen] > 0]
    if len(chosen) < s.min_detections:
        raise CalibrationError(
            f"sensor {sid}: only {len(chosen)} of its {total} detections follow a walking "
            f"person (need at least {s.min_detections}); the walker must cross its view"
        )
    t, xy, seg = t[chosen], xy[chosen], labels[chosen]
    smooth, vel, ok = _smooth(t, xy, seg, s.smooth_half_window_s)
    link = (seg[:-1] == seg[1:]) & (np.diff(t) <= s.max_interp_gap_s) & ok[:-1] & ok[1:]
    return _Walker(sid, t, xy, seg, smooth, vel, link, total)


def _bracket(w: _Walker, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For query times: left sample index, fraction towards the next, and validity."""
    n = len(w.t)
    left = np.searchsorted(w.t, tau, side="right") - 1
    inside = (left >= 0) & (left < n - 1)
    a = np.clip(left, 0, max(n - 2, 0))
    valid = inside & w.link[a] if n > 1 else np.zeros(len(tau), dtype=bool)
    dt = w.t[np.minimum(a + 1, n - 1)] - w.t[a]
    frac = np.clip((tau - w.t[a]) / np.where(dt > 0, dt, 1.0), 0.0, 1.0)
    return a, frac, valid


def _interp(
    w: _Walker, tau: np.ndarray, *, raw: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Trajectory and its velocity at ``tau``, with validity.

    The smoothed trajectory is a cubic Hermite spline through the local fit's positions
    and velocities, and the velocity returned is its exact derivative: the joint solve's
    residuals and its Jacobian in the clock offsets describe one smooth function. Raw
    detections (``raw``) are joined by straight lines (velocity: the lines' slopes).
    """
    a, f, valid = _bracket(w, tau)
    b = np.minimum(a + 1, len(w.t) - 1)
    h = (w.t[b] - w.t[a])[:, None]
    s = f[:, None]
    if raw:
        step = w.xy[b] - w.xy[a]
        return w.xy[a] + s * step, step / np.where(h > 0, h, 1.0), valid
    pa, pb, va, vb = w.smooth[a], w.smooth[b], w.vel[a] * h, w.vel[b] * h
    s2, s3 = s * s, s * s * s
    pos = (2 * s3 - 3 * s2 + 1) * pa + (s3 - 2 * s2 + s) * va + (3 * s2 - 2 * s3) * pb
    pos += (s3 - s2) * vb
    slope = (6 * s2 - 6 * s) * (pa - pb) + (3 * s2 - 4 * s + 1) * va + (3 * s2 - 2 * s) * vb
    return pos, np.where(h > 0, slope / np.where(h > 0, h, 1.0), w.vel[a]), valid


def _matches(wi: _Walker, wj: _Walker, lag: float) -> np.ndarray:
    """Indices of ``wi``'s samples whose instant ``wj`` can be interpolated at."""
    _, _, valid = _bracket(wj, wi.t + lag)
    return np.flatnonzero(valid)
