"""Detection-level sensor models: what a depth sensor's people detector would report.

For each frame a :class:`SensorModel` decides, person by person, whether the detector
would find them and where it would put them:

* **field of view and range** of the sensor type, tested on sample points of the body
  (head, shoulders, chest, hips, knees) in the sensor's optical frame;
* **line of sight**: each sample point can be hidden by another person (a vertical
  cylinder) or a piece of furniture (a box) between it and the sensor;
* **detection**: the head must be visible (detectors look for heads) and enough of the
  body; then a miss probability that grows past the type's reliable range;
* **noise**: along the viewing ray with a standard deviation ``s0 + s1*d + s2*d**2``
  (Kinect v1 grows with distance squared, time-of-flight sensors are nearly constant)
  and across it, plus height noise;
* **merges and splits**: two people closer than ``merge_distance_m`` become one
  detection at their mean; rarely one person splits into two blobs;
* **clutter**: Poisson false positives on free floor in view, with low confidence;
* **calibration error**: detections are mapped to the world with the pose the sensor
  *believes*, which may differ from its true pose.

Confidence is on ``[0, 1]``; true people score roughly 0.6-0.95 depending on how much of
them is visible, clutter roughly 0.1-0.5.

Field of view, ranges and rate are the sensor type's facts
(:mod:`openptrack_py.sensor_types`); the noise, miss, clutter and split figures per type
are the simulator's own model (:data:`SENSOR_NOISE`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from openptrack_py.config import Pose, PoseError, SensorConfig
from openptrack_py.errors import ConfigError
from openptrack_py.geometry import invert, world_from_optical
from openptrack_py.messages.detection import Detection
from openptrack_py.sensor_types import SENSOR_TYPES, SensorType
from openptrack_py.sim.world import Room, Snapshot

APPEARANCE_BINS = 16
"""Hue bins of the simulated appearance signature (each 22.5 degrees)."""


@dataclass(frozen=True)
class SensorNoise:
    """How the simulated detector of one sensor type errs.

    The type's geometry (image, field of view, ranges, rate) is in
    :data:`openptrack_py.sensor_types.SENSOR_TYPES`.

    Parameters
    ----------
    depth_sigma : tuple of float
        ``(s0, s1, s2)``: centroid noise along the ray ``s0 + s1*d + s2*d**2`` metres.
    lateral_sigma_m : float
        Centroid noise across the ray, metres.
    height_sigma_m : float
        Noise of the measured height, metres.
    miss_probability : float
        Probability of missing a fully visible person within the reliable range.
    clutter_per_frame : float
        Mean number of false detections per frame.
    split_probability : float
        Probability that a detected person also yields a second, spurious blob.
    """

    depth_sigma: tuple[float, float, float]
    lateral_sigma_m: float
    height_sigma_m: float
    miss_probability: float
    clutter_per_frame: float
    split_probability: float

    def depth_sigma_at(self, distance_m: np.ndarray | float) -> np.ndarray:
        """Standard deviation of the centroid along the ray at ``distance_m``."""
        s0, s1, s2 = self.depth_sigma
        d = np.asarray(distance_m, dtype=float)
        return s0 + s1 * d + s2 * d * d


SENSOR_NOISE: dict[str, SensorNoise] = {
    "kinect1": SensorNoise(
        depth_sigma=(0.02, 0.0, 0.0035), lateral_sigma_m=0.03, height_sigma_m=0.04,
        miss_probability=0.05, clutter_per_frame=0.02, split_probability=0.004,
    ),
    "kinect2": SensorNoise(
        depth_sigma=(0.03, 0.002, 0.0), lateral_sigma_m=0.025, height_sigma_m=0.03,
        miss_probability=0.02, clutter_per_frame=0.03, split_probability=0.003,
    ),
    "realsense": SensorNoise(
        depth_sigma=(0.03, 0.003, 0.0), lateral_sigma_m=0.025, height_sigma_m=0.03,
        miss_probability=0.03, clutter_per_frame=0.04, split_probability=0.004,
    ),
    "sr4500": SensorNoise(
        depth_sigma=(0.03, 0.002, 0.0), lateral_sigma_m=0.04, height_sigma_m=0.04,
        miss_probability=0.05, clutter_per_frame=0.03, split_probability=0.004,
    ),
}  # fmt: skip
"""The simulated detector's noise per sensor type (the types of ``SENSOR_TYPES``)."""


@dataclass(frozen=True)
class SensorSpec:
    """One simulated sensor: type, pose and fault model.

    Parameters
    ----------
    id : str
        Sensor id.
    type : SensorType
        Nominal facts of the sensor's type.
    pose : Pose
        True pose in the world.
    rate_hz : float
        Frame rate.
    clock_offset_s : float
        Constant offset added to every stamp the sensor writes.
    latency_s, latency_jitter_s : float
        Mean capture-to-publication delay and its standard deviation.
    miss_probability, clutter_per_frame : float
        This sensor's figures, used instead of those of its noise model
        (:meth:`from_config` takes them from the type's when the config leaves them out).
    frame_drop_probability : float
        Probability that a whole frame is never published.
    pose_error : PoseError
        Believed pose minus true pose.
    phase_s : float
        Time of the first frame after the scenario start.
    noise_override : SensorNoise, optional
        A noise model replacing the type's (see :attr:`noise`).
    """

    id: str
    type: SensorType
    pose: Pose
    rate_hz: float
    clock_offset_s: float = 0.0
    latency_s: float = 0.03
    latency_jitter_s: float = 0.005
    miss_probability: float = 0.02
    clutter_per_frame: float = 0.03
    frame_drop_probability: float = 0.0
    pose_error: PoseError = field(default_factory=PoseError)
    phase_s: float = 0.0
    noise_override: SensorNoise | None = None

    @property
    def noise(self) -> SensorNoise:
        """The simulated detector's noise model: ``noise_override`` or the type's."""
        if self.noise_override is not None:
            return self.noise_override
        return SENSOR_NOISE[self.type.name]

    @classmethod
    def from_config(cls, cfg: SensorConfig, phase_s: float = 0.0) -> SensorSpec:
        """Build from a network file's sensor entry, filling type defaults.

        Raises
        ------
        ConfigError
            If the sensor has no pose (simulated sensors need one).
        """
        if cfg.pose is None:
            raise ConfigError(f"sensors.{cfg.id}.pose: a simulated sensor needs a pose")
        kind = SENSOR_TYPES[cfg.type]
        noise = SENSOR_NOISE[cfg.type]
        return cls(
            id=cfg.id,
            type=kind,
            pose=cfg.pose,
            rate_hz=cfg.rate_hz or kind.rate_hz,
            clock_offset_s=cfg.clock_offset_s,
            latency_s=cfg.latency_s,
            latency_jitter_s=cfg.latency_jitter_s,
            miss_probability=(
                noise.miss_probability if cfg.miss_probability is None else cfg.miss_probability
            ),
            clutter_per_frame=(
                noise.clutter_per_frame if cfg.clutter_per_frame is None else cfg.clutter_per_frame
            ),
            frame_drop_probability=cfg.frame_drop_probability,
            pose_error=cfg.pose_error,
            phase_s=phase_s,
        )


@dataclass(frozen=True)
class Observation:
    """What one sensor reported in one frame, with the truth behind it.

    Parameters
    ----------
    detections : tuple of Detection
        World-frame detections (through the believed pose).
    person_ids : tuple of int
        Ground-truth person id behind each detection; 0 for clutter.
    """

    detections: tuple[Detection, ...]
    person_ids: tuple[int, ...]


# Body sample points: (height fraction, lateral offset in body radii, weight).
_BODY_POINTS = np.array(
    [
        (0.93, 0.0, 0.0),  # head (must be visible)
        (0.78, -0.8, 1.0),  # shoulders
        (0.78, 0.8, 1.0),
        (0.62, 0.0, 1.0),  # chest
        (0.48, -0.7, 1.0),  # hips
        (0.48, 0.7, 1.0),
        (0.25, 0.0, 1.0),  # knees
    ]
)
_HEAD = 0


class SensorModel:
    """Turns the world's state into one sensor's detections.

    Parameters
    ----------
    spec : SensorSpec
        The sensor.
    room : Room
        The room (for furniture occlusion and clutter placement).
    rng : numpy.random.Generator
        This sensor's own randomness.
    merge_distance_m : float
        People closer than this (centre to centre) come out as one detection.
    """

    def __init__(
        self,
        spec: SensorSpec,
        room: Room,
        rng: np.random.Generator,
        merge_distance_m: float = 0.3,
    ) -> None:
        self.spec = spec
        self.room = room
        self.rng = rng
        self.merge_distance_m = merge_distance_m
        self.world_from_camera = world_from_optical(spec.pose)
        self.camera_from_world = invert(self.world_from_camera)
        believed = spec.pose.model_copy(
            update={
                "x": spec.pose.x + spec.pose_error.dx,
                "y": spec.pose.y + spec.pose_error.dy,
                "yaw_deg": spec.pose.yaw_deg + spec.pose_error.dyaw_deg,
            }
        )
        # true world -> camera -> world as the sensor believes it to be placed
        self.reported_from_world = world_from_optical(believed) @ self.camera_from_world
        self.origin = self.world_from_camera[:3, 3].copy()
        kind = spec.type
        self._tan_h = math.tan(math.radians(kind.hfov_deg) / 2)
        self._tan_v = math.tan(math.radians(kind.vfov_deg) / 2)
        self._obstacles = np.array(
            [(o.x0, o.y0, o.x1, o.y1, o.height) for o in room.obstacles], dtype=float
        ).reshape(-1, 5)

    # ------------------------------------------------------------------ geometry

    def in_view(self, points: np.ndarray) -> np.ndarray:
        """Mask of world points inside the field of view and depth range."""
        cam = points @ self.camera_from_world[:3, :3].T + self.camera_from_world[:3, 3]
        z = cam[..., 2]
        rng = np.linalg.norm(cam, axis=-1)
        return (
            (z > 1e-6)
            & (np.abs(cam[..., 0]) <= self._tan_h * z)
            & (np.abs(cam[..., 1]) <= self._tan_v * z)
            & (rng >= self.spec.type.min_range_m)
            & (rng <= self.spec.type.max_range_m)
        )

    def covers(self, pos: np.ndarray, height: np.ndarray) -> np.ndarray:
        """Mask of people whose head is in view (occlusion ignored)."""
        if len(pos) == 0:
            return np.zeros(0, dtype=bool)
        heads = np.column_stack([pos, _BODY_POINTS[_HEAD, 0] * height])
        return self.in_view(heads)

    def _body_points(self, snap: Snapshot) -> tuple[np.ndarray, np.ndarray]:
        """World sample points ``(n, K, 3)`` and the unit ray direction on the floor."""
        ray = snap.pos - self.origin[:2]
        ray /= np.maximum(np.linalg.norm(ray, axis=1, keepdims=True), 1e-9)
        side = np.column_stack([-ray[:, 1], ray[:, 0]])
        frac, lateral = _BODY_POINTS[:, 0], _BODY_POINTS[:, 1]
        xy = (
            snap.pos[:, None, :]
            + (lateral[None, :, None] * snap.radius[:, None, None]) * (side[:, None, :])
        )
        z = frac[None, :] * snap.height[:, None]
        return np.concatenate([xy, z[..., None]], axis=2), ray

    def _in_wedge(self, pos: np.ndarray, radius: np.ndarray) -> np.ndarray:
        """Mask of floor discs that reach into the horizontal field of view."""
        rel = pos - self.origin[:2]
        dist = np.maximum(np.linalg.norm(rel, axis=1), 1e-6)
        bearing = np.arctan2(rel[:, 1], rel[:, 0]) - math.radians(self.spec.pose.yaw_deg)
        bearing = (bearing + math.pi) % (2 * math.pi) - math.pi
        half = math.radians(self.spec.type.hfov_deg) / 2 + 0.1  # margin for tilt and roll
        return (np.abs(bearing) <= half + np.arcsin(np.minimum(radius / dist, 1.0))) | (dist < 1.0)

    def _occluded(
        self,
        points: np.ndarray,
        owner: np.ndarray,
        centres: np.ndarray,
        radius: np.ndarray,
        height: np.ndarray,
    ) -> np.ndarray:
        """Mask of ``points`` (M, 3) hidden by people (given cylinders) or furniture.

        ``owner[i]`` is the row of the cylinder that point ``i`` belongs to (never its
        own occluder), or -1.
        """
        hidden = np.zeros(len(points), dtype=bool)
        if len(points) == 0:
            return hidden
        s = self.origin
        d = points - s  # (M, 3)
        dxy = d[:, :2]
        len2 = np.maximum(np.einsum("ij,ij->i", dxy, dxy), 1e-12)
        if len(centres):
            # people as vertical cylinders: closest approach of the ray's floor projection
            c = centres - s[:2]  # (n, 2)
            t = (dxy @ c.T) / len2[:, None]  # (M, n)
            cx = t * dxy[:, 0:1] - c[None, :, 0]
            cy = t * dxy[:, 1:2] - c[None, :, 1]
            z_at = s[2] + t * d[:, 2:3]
            hit = (
                (t > 0.0)
                & (t < 1.0)
                & (cx * cx + cy * cy < (radius**2)[None, :])
                & (z_at < height[None, :])
            )
            mine = owner >= 0
            hit[np.flatnonzero(mine), owner[mine]] = False
            hidden |= hit.any(axis=1)
        # furniture as boxes: slab test on the floor, then the ray's height inside
        for x0, y0, x1, y1, top in self._obstacles:
            with np.errstate(divide="ignore", invalid="ignore"):
                tx0 = (x0 - s[0]) / dxy[:, 0]
                tx1 = (x1 - s[0]) / dxy[:, 0]
                ty0 = (y0 - s[1]) / dxy[:, 1]
                ty1 = (y1 - s[1]) / dxy[:, 1]
            inside_x = (s[0] > x0) & (s[0] < x1)
            inside_y = (s[1] > y0) & (s[1] < y1)
            t_enter = np.maximum(
                np.where(
                    dxy[:, 0] == 0, np.where(inside_x, -np.inf, np.inf), np.minimum(tx0, tx1)
                ),
                np.where(
                    dxy[:, 1] == 0, np.where(inside_y, -np.inf, np.inf), np.minimum(ty0, ty1)
                ),
            )
            t_exit = np.minimum(
                np.where(
                    dxy[:, 0] == 0, np.where(inside_x, np.inf, -np.inf), np.maximum(tx0, tx1)
                ),
                np.where(
                    dxy[:, 1] == 0, np.where(inside_y, np.inf, -np.inf), np.maximum(ty0, ty1)
                ),
            )
            t_in = np.clip(t_enter, 0.0, 1.0)
            t_out = np.clip(t_exit, 0.0, 1.0)
            crosses = (t_enter < t_exit) & (t_enter < 1.0) & (t_exit > 0.0)
            z_low = s[2] + np.minimum(t_in, t_out) * d[:, 2]
            z_high = s[2] + np.maximum(t_in, t_out) * d[:, 2]
            hidden |= crosses & (np.minimum(z_low, z_high) < top)
        return hidden

    def visibility(self, snap: Snapshot) -> tuple[np.ndarray, np.ndarray]:
        """Per person: whether the head is visible, and the visible body fraction."""
        n = len(snap)
        if n == 0:
            return np.zeros(0, dtype=bool), np.zeros(0)
        points, _ = self._body_points(snap)
        k = points.shape[1]
        flat = points.reshape(-1, 3)
        visible = self.in_view(flat)
        candidates = np.flatnonzero(visible)
        if len(candidates):
            owner = candidates // k
            # Only people inside the (slightly widened) horizontal field of view can stand
            # between the sensor and a point in view.
            blockers = np.flatnonzero(self._in_wedge(snap.pos, snap.radius))
            remap = np.full(n, -1)
            remap[blockers] = np.arange(len(blockers))
            visible[candidates] &= ~self._occluded(
                flat[candidates], remap[owner], snap.pos[blockers], snap.radius[blockers],
                snap.height[blockers],
            )  # fmt: skip
        visible = visible.reshape(n, k)
        weights = _BODY_POINTS[:, 2]
        fraction = (visible * weights).sum(axis=1) / weights.sum()
        return visible[:, _HEAD], fraction

    # --------------------------------------------------------------- observation

    def _miss_probability(self, distance: np.ndarray) -> np.ndarray:
        kind = self.spec.type
        span = max(kind.max_range_m - kind.reliable_range_m, 1e-6)
        beyond = np.clip((distance - kind.reliable_range_m) / span, 0.0, 1.0)
        base = self.spec.miss_probability
        return base + (1.0 - base) * beyond**2

    def observe(self, snap: Snapshot) -> Observation:
        """Simulate one frame of the detector on the world state ``snap``."""
        rng = self.rng
        kind = self.spec.type
        noise = self.spec.noise
        positions: list[np.ndarray] = []
        heights: list[float] = []
        confidences: list[float] = []
        person_ids: list[int] = []
        source_rows: list[int] = []

        n = len(snap)
        if n:
            head_visible, fraction = self.visibility(snap)
            centroid = np.column_stack([snap.pos, 0.55 * snap.height])
            distance = np.linalg.norm(centroid - self.origin, axis=1)
            p_detect = (1.0 - self._miss_probability(distance)) * np.clip(
                (fraction - 0.25) / 0.45, 0.0, 1.0
            )
            p_detect[~head_visible] = 0.0
            detected = np.flatnonzero(rng.random(n) < p_detect)
            if len(detected):
                ray = snap.pos[detected] - self.origin[:2]
                ray /= np.maximum(np.linalg.norm(ray, axis=1, keepdims=True), 1e-9)
                side = np.column_stack([-ray[:, 1], ray[:, 0]])
                sigma = noise.depth_sigma_at(distance[detected])
                along = rng.normal(0.0, 1.0, len(detected)) * sigma
                across = rng.normal(0.0, noise.lateral_sigma_m, len(detected))
                xy = snap.pos[detected] + along[:, None] * ray + across[:, None] * side
                frac = fraction[detected]
                # with the legs hidden the visible centroid rides higher
                z = snap.height[detected] * (0.55 + 0.15 * (1.0 - frac))
                z = z + rng.normal(0.0, 0.03, len(detected))
                h = snap.height[detected] + rng.normal(0.0, noise.height_sigma_m, len(detected))
                far = np.maximum(distance[detected] - kind.reliable_range_m, 0.0)
                conf = 0.55 + 0.35 * frac - 0.04 * far + rng.normal(0.0, 0.06, len(detected))
                for j, row in enumerate(detected):
                    positions.append(np.array([xy[j, 0], xy[j, 1], z[j]]))
                    heights.append(float(h[j]))
                    confidences.append(float(np.clip(conf[j], 0.3, 1.0)))
                    person_ids.append(int(snap.ids[row]))
                    source_rows.append(int(row))
                self._merge(snap, positions, heights, confidences, person_ids, source_rows)
                self._split(positions, heights, confidences, person_ids, source_rows)
        self._clutter(positions, heights, confidences, person_ids, source_rows)
        return self._finish(snap, positions, heights, confidences, person_ids, source_rows)

    def _merge(
        self,
        snap: Snapshot,
        positions: list[np.ndarray],
        heights: list[float],
        confidences: list[float],
        person_ids: list[int],
        rows: list[int],
    ) -> None:
        """People standing closer than the merge distance come out as one blob."""
        if len(rows) < 2:
            return
        true_xy = snap.pos[rows]
        gap = np.linalg.norm(true_xy[:, None] - true_xy[None], axis=2)
        reach = self.merge_distance_m
        keep = list(range(len(rows)))
        merged: set[int] = set()
        for a in range(len(rows)):
            if a in merged:
                continue
            group = [b for b in range(a + 1, len(rows)) if b not in merged and gap[a, b] < reach]
            if not group:
                continue
            members = [a, *group]
            positions[a] = np.mean([positions[m] for m in members], axis=0)
            heights[a] = max(heights[m] for m in members)
            confidences[a] = max(confidences[m] for m in members)
            merged.update(group)
        keep = [i for i in keep if i not in merged]
        for target in (positions, heights, confidences, person_ids, rows):
            target[:] = [target[i] for i in keep]

    def _split(
        self,
        positions: list[np.ndarray],
        heights: list[float],
        confidences: list[float],
        person_ids: list[int],
        rows: list[int],
    ) -> None:
        """Rarely, a person also yields a spurious second blob beside them."""
        p = self.spec.noise.split_probability
        for i in range(len(rows)):
            if self.rng.random() >= p:
                continue
            angle = self.rng.uniform(0, 2 * math.pi)
            offset = self.rng.uniform(0.35, 0.6) * np.array([math.cos(angle), math.sin(angle), 0])
            positions.append(positions[i] + offset)
            heights.append(heights[i] * self.rng.uniform(0.6, 0.9))
            confidences.append(float(self.rng.uniform(0.2, 0.5)))
            person_ids.append(0)
            rows.append(-1)

    def _clutter(
        self,
        positions: list[np.ndarray],
        heights: list[float],
        confidences: list[float],
        person_ids: list[int],
        rows: list[int],
    ) -> None:
        """Poisson false positives on free floor in view."""
        kind = self.spec.type
        count = self.rng.poisson(self.spec.clutter_per_frame)
        for _ in range(count):
            rng_m = self.rng.uniform(kind.min_range_m + 0.5, kind.reliable_range_m)
            azimuth = self.rng.uniform(-0.45, 0.45) * math.radians(kind.hfov_deg)
            yaw = math.radians(self.spec.pose.yaw_deg) + azimuth
            xy = self.origin[:2] + rng_m * np.array([math.cos(yaw), math.sin(yaw)])
            if not self.room.free(xy, 0.1)[0]:
                continue
            h = float(self.rng.uniform(0.9, 2.0))
            positions.append(np.array([xy[0], xy[1], 0.55 * h]))
            heights.append(h)
            confidences.append(float(np.clip(self.rng.beta(2.0, 4.0), 0.05, 0.6)))
            person_ids.append(0)
            rows.append(-1)

    def _finish(
        self,
        snap: Snapshot,
        positions: list[np.ndarray],
        heights: list[float],
        confidences: list[float],
        person_ids: list[int],
        rows: list[int],
    ) -> Observation:
        if not positions:
            return Observation((), ())
        true_world = np.array(positions)
        reported = (
            true_world @ self.reported_from_world[:3, :3].T + self.reported_from_world[:3, 3]
        )
        distance = np.linalg.norm(true_world - self.origin, axis=1)
        row_idx = np.array(rows, dtype=int)
        real = row_idx >= 0
        radius = np.full(len(rows), 0.25)  # clutter: a person-sized box
        radius[real] = snap.radius[row_idx[real]]
        height = np.clip(np.array(heights), 0.0, 10.0)
        boxes = self._boxes(true_world[:, :2], height, radius).tolist()
        looks = self._appearance(snap, row_idx).tolist()
        conf = np.clip(np.array(confidences), 0.0, 1.0).tolist()
        rep = reported.tolist()
        dist = distance.tolist()
        hts = height.tolist()
        detections = tuple(
            Detection(
                x=rep[i][0],
                y=rep[i][1],
                z=rep[i][2],
                height=hts[i],
                confidence=conf[i],
                distance=dist[i],
                bbox=tuple(boxes[i]),
                appearance=tuple(looks[i]),
            )
            for i in range(len(rows))
        )
        return Observation(detections, tuple(person_ids))

    def _boxes(self, xy: np.ndarray, height: np.ndarray, radius: np.ndarray) -> np.ndarray:
        """Image boxes ``(u, v, w, h)`` of standing cylinders, clipped to the image."""
        fx, fy, cx, cy = self.spec.type.intrinsics
        ray = xy - self.origin[:2]
        ray /= np.maximum(np.linalg.norm(ray, axis=1, keepdims=True), 1e-9)
        side = np.column_stack([-ray[:, 1], ray[:, 0]]) * radius[:, None]
        n = len(xy)
        corners = np.empty((n, 4, 3))
        corners[:, 0, :2] = corners[:, 2, :2] = xy + side
        corners[:, 1, :2] = corners[:, 3, :2] = xy - side
        corners[:, :2, 2] = 0.0
        corners[:, 2:, 2] = height[:, None]
        cam = corners @ self.camera_from_world[:3, :3].T + self.camera_from_world[:3, 3]
        z = np.maximum(cam[..., 2], 1e-3)
        u = np.clip(fx * cam[..., 0] / z + cx, 0, self.spec.type.width - 1)
        v = np.clip(fy * cam[..., 1] / z + cy, 0, self.spec.type.height - 1)
        u0, u1 = u.min(axis=1).astype(int), u.max(axis=1).astype(int)
        v0, v1 = v.min(axis=1).astype(int), v.max(axis=1).astype(int)
        return np.column_stack([u0, v0, u1 - u0, v1 - v0])

    def _appearance(self, snap: Snapshot, rows: np.ndarray) -> np.ndarray:
        """Quantised hue histograms of the visible clothing (noise for clutter)."""
        rng = self.rng
        n = len(rows)
        hist = np.full((n, APPEARANCE_BINS), 0.02)
        real = rows >= 0
        width = 360.0 / APPEARANCE_BINS
        idx = np.flatnonzero(real)
        for hues, weight in ((snap.top_hue, 0.55), (snap.bottom_hue, 0.35)):
            b = (hues[rows[idx]] // width).astype(int) % APPEARANCE_BINS
            for offset, share in ((0, 0.8), (1, 0.1), (-1, 0.1)):
                np.add.at(hist, (idx, (b + offset) % APPEARANCE_BINS), weight * share)
        hist[idx, 1] += 0.08  # skin
        fake = np.flatnonzero(~real)
        hist[fake] += rng.random((len(fake), APPEARANCE_BINS))
        hist *= rng.gamma(20.0, 1 / 20.0, hist.shape)  # lighting and segmentation noise
        hist = hist / hist.sum(axis=1, keepdims=True) * 255.0
        return np.round(hist).astype(int)
