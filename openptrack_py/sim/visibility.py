"""A simulated sensor's view: field of view, depth range and line of sight.

:class:`SensorView` answers, for world points and for people, whether a sensor can see
them: inside its field of view and depth range, and not hidden by another person (a
vertical cylinder) or a piece of furniture (a box) between them and the sensor. A person
is sampled at a few body points (head, shoulders, chest, hips, knees): detectors look for
heads, so the head must show, and how much of the rest shows sets the chance of detection.
"""

from __future__ import annotations

import math

import numpy as np

from openptrack_py.geometry import invert, world_from_optical
from openptrack_py.sim.sensor_spec import SensorSpec
from openptrack_py.sim.world import Room, Snapshot

# Body sample points: (height fraction, lateral offset in body radii, weight).
BODY_POINTS = np.array(
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
HEAD = 0


STEEP_PITCH_DEG = 45.0
"""Above this tilt the field of view is not a wedge on the floor around the heading."""


class SensorView:
    """Where one sensor looks and what it can see: field of view, range, line of sight.

    Parameters
    ----------
    spec : SensorSpec
        The sensor.
    room : Room
        The room (its furniture hides people).
    """

    def __init__(self, spec: SensorSpec, room: Room) -> None:
        self.spec = spec
        self.room = room
        self.world_from_camera = world_from_optical(spec.pose)
        self.camera_from_world = invert(self.world_from_camera)
        self.origin = self.world_from_camera[:3, 3].copy()
        kind = spec.type
        self._tan_h = math.tan(math.radians(kind.hfov_deg) / 2)
        self._tan_v = math.tan(math.radians(kind.vfov_deg) / 2)
        self._obstacles = np.array(
            [(o.x0, o.y0, o.x1, o.y1, o.height) for o in room.obstacles], dtype=float
        ).reshape(-1, 5)

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
        heads = np.column_stack([pos, BODY_POINTS[HEAD, 0] * height])
        return self.in_view(heads)

    def _body_points(self, snap: Snapshot) -> tuple[np.ndarray, np.ndarray]:
        """World sample points ``(n, K, 3)`` and the unit ray direction on the floor."""
        ray = snap.pos - self.origin[:2]
        ray /= np.maximum(np.linalg.norm(ray, axis=1, keepdims=True), 1e-9)
        side = np.column_stack([-ray[:, 1], ray[:, 0]])
        frac, lateral = BODY_POINTS[:, 0], BODY_POINTS[:, 1]
        xy = (
            snap.pos[:, None, :]
            + (lateral[None, :, None] * snap.radius[:, None, None]) * (side[:, None, :])
        )
        z = frac[None, :] * snap.height[:, None]
        return np.concatenate([xy, z[..., None]], axis=2), ray

    def _in_wedge(self, pos: np.ndarray, radius: np.ndarray) -> np.ndarray:
        """Mask of floor discs that reach into the horizontal field of view."""
        if self.spec.pose.pitch_deg > STEEP_PITCH_DEG:  # no horizontal wedge looking down
            return np.ones(len(pos), dtype=bool)
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

    def visibility_mask(self, snap: Snapshot) -> np.ndarray:
        """Per person and body sample point (:data:`BODY_POINTS`): whether the sensor sees it.

        Returns
        -------
        ndarray of bool, shape (n, K)
            Row ``i`` is person ``i``; a point is seen when it is inside the field of view
            and depth range and no other person or piece of furniture hides it.
        """
        n = len(snap)
        if n == 0:
            return np.zeros((0, len(BODY_POINTS)), dtype=bool)
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
        return visible.reshape(n, k)

    def visibility(self, snap: Snapshot) -> tuple[np.ndarray, np.ndarray]:
        """Per person: whether the head is visible, and the visible body fraction."""
        return visible_summary(self.visibility_mask(snap))

    def sees(self, points: np.ndarray) -> np.ndarray:
        """Mask of world points ``(M, 3)`` in view and not hidden by furniture (people ignored)."""
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        seen = self.in_view(points)
        candidates = np.flatnonzero(seen)
        if len(candidates):
            none = np.zeros((0, 2))
            seen[candidates] &= ~self._occluded(
                points[candidates], np.full(len(candidates), -1), none, np.zeros(0), np.zeros(0)
            )
        return seen


def visible_summary(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whether the head is visible, and the visible body fraction, from a visibility mask.

    Parameters
    ----------
    mask : ndarray of bool, shape (n, K)
        As returned by :meth:`SensorView.visibility_mask`.
    """
    if len(mask) == 0:
        return np.zeros(0, dtype=bool), np.zeros(0)
    weights = BODY_POINTS[:, 2]
    fraction = (mask * weights).sum(axis=1) / weights.sum()
    return mask[:, HEAD], fraction


def visible_lateral_offset(mask: np.ndarray) -> np.ndarray:
    """Sideways offset of the visible body points' centroid, in body radii.

    The mean lateral position (:data:`BODY_POINTS`, positive to the left as the sensor
    looks) of the weighted visible sample points; 0 for a fully visible or a fully hidden
    person. A detector that takes the centroid of the points it sees puts a half-hidden
    person off-centre, towards their visible side.

    Parameters
    ----------
    mask : ndarray of bool, shape (n, K)
        As returned by :meth:`SensorView.visibility_mask`.

    Returns
    -------
    ndarray, shape (n,)
        The offset of each person, in body radii.
    """
    weights = BODY_POINTS[:, 2] * mask
    total = weights.sum(axis=1)
    lateral = (weights * BODY_POINTS[:, 1]).sum(axis=1)
    return np.where(total > 0, lateral / np.maximum(total, 1e-12), 0.0)
