"""The simulated world: a room with obstacles and people who walk in it.

People move by a small social-force model stepped at a fixed ``dt``: each person is
driven towards the velocity its scenario's :class:`Director` asks for, and pushed away
from other people, walls and furniture. Stepping is deterministic for a given seed.
Positions between two steps are linearly interpolated, so sensors and ground truth can
sample the world at any time in non-decreasing order.

Who the people are and a snapshot of their state are in :mod:`~openptrack_py.sim.people`
(re-exported here). A person keeps their id for the whole run: a director may take
someone out of the room and bring them back later with :meth:`World.add_person`'s
``person_id``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from openptrack_py.sim.people import PersonKind, PersonSpec, Snapshot, random_person

__all__ = [
    "Director",
    "Obstacle",
    "PersonKind",
    "PersonSpec",
    "Room",
    "Snapshot",
    "World",
    "random_person",
]

# Obstacle faces as (axis, outward sign): -x, +x, -y, +y.
_FACES = ((0, -1.0), (0, 1.0), (1, -1.0), (1, 1.0))


@dataclass(frozen=True)
class Obstacle:
    """An axis-aligned block of furniture (or a pillar) standing on the floor.

    Parameters
    ----------
    name : str
        Label.
    x0, y0, x1, y1 : float
        Footprint corners, metres (``x0 < x1``, ``y0 < y1``).
    height : float
        Top of the block above the floor, metres. It hides what is behind it only below
        that height.
    """

    name: str
    x0: float
    y0: float
    x1: float
    y1: float
    height: float


@dataclass(frozen=True)
class Room:
    """A rectangular room ``[0, width] x [0, depth]`` with obstacles and doors.

    Parameters
    ----------
    width, depth : float
        Extent along x and y, metres.
    obstacles : tuple of Obstacle
        Furniture.
    doors : tuple of (float, float)
        Points on the walls where people enter and leave.
    """

    width: float
    depth: float
    obstacles: tuple[Obstacle, ...] = ()
    doors: tuple[tuple[float, float], ...] = ()

    def contains(self, xy: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Mask of points inside the room, at least ``margin`` from the walls."""
        xy = np.atleast_2d(xy)
        return (
            (xy[:, 0] >= margin)
            & (xy[:, 0] <= self.width - margin)
            & (xy[:, 1] >= margin)
            & (xy[:, 1] <= self.depth - margin)
        )

    def free(self, xy: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Mask of points inside the room and outside every obstacle (grown by ``margin``)."""
        xy = np.atleast_2d(xy)
        ok = self.contains(xy, margin)
        for o in self.obstacles:
            inside = (
                (xy[:, 0] > o.x0 - margin)
                & (xy[:, 0] < o.x1 + margin)
                & (xy[:, 1] > o.y0 - margin)
                & (xy[:, 1] < o.y1 + margin)
            )
            ok &= ~inside
        return ok

    def random_free_point(
        self, rng: np.random.Generator, margin: float = 0.4, tries: int = 1000
    ) -> np.ndarray:
        """A uniformly drawn point of free floor."""
        for _ in range(tries):
            p = rng.uniform((margin, margin), (self.width - margin, self.depth - margin))
            if self.free(p, margin)[0]:
                return p
        raise RuntimeError("room has no free floor for the requested margin")


class Director(Protocol):
    """A scenario's script: who is in the room and where they want to go.

    ``update`` runs before every world step; it may add or remove people and must set
    ``world.v_des`` (desired velocity) for every active person.
    """

    def start(self, world: World) -> None:
        """Put the initial people in the world."""

    def update(self, world: World, t: float) -> None:
        """Steer people at scenario time ``t`` (seconds since the start)."""


class World:
    """People in a room, stepped by a social-force model.

    Parameters
    ----------
    room : Room
        The room.
    director : Director
        The scenario script.
    rng : numpy.random.Generator
        Randomness of the script and the motion.
    dt : float
        Step, seconds.
    """

    # Social-force constants (Helbing & Molnar style), tuned for calm indoor walking.
    RELAX_S = 0.4
    PERSON_A = 3.0
    PERSON_B = 0.25
    WALL_A = 4.0
    WALL_B = 0.15
    MAX_SPEED = 3.5

    def __init__(
        self, room: Room, director: Director, rng: np.random.Generator, dt: float = 0.04
    ) -> None:
        self.room = room
        self.director = director
        self.rng = rng
        self.dt = dt
        self.t = 0.0
        capacity = 16
        self.ids = np.zeros(capacity, dtype=np.int64)
        self.active = np.zeros(capacity, dtype=bool)
        self.pos = np.zeros((capacity, 2))
        self.vel = np.zeros((capacity, 2))
        self.v_des = np.zeros((capacity, 2))
        self.height = np.zeros(capacity)
        self.radius = np.zeros(capacity)
        self.speed = np.zeros(capacity)
        self.top_hue = np.zeros(capacity)
        self.bottom_hue = np.zeros(capacity)
        self.top_saturation = np.zeros(capacity)
        self.top_value = np.zeros(capacity)
        self.bottom_saturation = np.zeros(capacity)
        self.bottom_value = np.zeros(capacity)
        self.heading = np.zeros(capacity)
        self.kind = np.zeros(capacity, dtype="<U5")
        self._next_id = 1
        self.director.start(self)
        self._prev = self.snapshot()
        self._cur = self._prev

    # -------------------------------------------------------------- population

    def _grow(self) -> None:
        n = len(self.ids) * 2
        for name in (
            "ids", "active", "pos", "vel", "v_des", "height", "radius", "speed",
            "top_hue", "bottom_hue", "top_saturation", "top_value", "bottom_saturation",
            "bottom_value", "heading", "kind",
        ):  # fmt: skip
            old = getattr(self, name)
            new = np.zeros((n, *old.shape[1:]), dtype=old.dtype)
            new[: len(old)] = old
            setattr(self, name, new)

    HEADING_MIN_SPEED = 0.2
    """People walking at least this fast (m/s) face where they walk; slower, they keep
    the heading they had."""

    def add_person(
        self,
        spec: PersonSpec,
        xy: np.ndarray | tuple[float, float],
        person_id: int | None = None,
    ) -> int:
        """Place a person at ``xy``; return their slot index.

        Parameters
        ----------
        spec : PersonSpec
            Who they are.
        xy : array_like
            Where they appear.
        person_id : int, optional
            Their ground-truth id: someone coming back keeps the id they had. A fresh id
            when omitted.

        Raises
        ------
        ValueError
            If ``person_id`` is not positive or someone with it is in the world.
        """
        if person_id is not None:
            if person_id < 1:
                raise ValueError(f"add_person: person_id must be >= 1 (received {person_id})")
            if (self.active & (self.ids == person_id)).any():
                raise ValueError(f"add_person: person {person_id} is already in the world")
        free = np.flatnonzero(~self.active)
        if len(free) == 0:
            self._grow()
            free = np.flatnonzero(~self.active)
        slot = int(free[0])
        if person_id is None:
            person_id = self._next_id
        self.ids[slot] = person_id
        self._next_id = max(self._next_id, person_id + 1)
        self.active[slot] = True
        self.pos[slot] = xy
        self.vel[slot] = 0.0
        self.v_des[slot] = 0.0
        self.height[slot] = spec.height
        self.radius[slot] = spec.radius
        self.speed[slot] = spec.speed
        self.top_hue[slot] = spec.top_hue
        self.bottom_hue[slot] = spec.bottom_hue
        self.top_saturation[slot] = spec.top_saturation
        self.top_value[slot] = spec.top_value
        self.bottom_saturation[slot] = spec.bottom_saturation
        self.bottom_value[slot] = spec.bottom_value
        self.heading[slot] = person_id * 2.4  # as the renderer turns a standing body
        self.kind[slot] = spec.kind
        return slot

    def remove_person(self, slot: int) -> None:
        """Take the person in ``slot`` out of the world."""
        self.active[slot] = False

    @property
    def slots(self) -> np.ndarray:
        """Indices of the active people."""
        return np.flatnonzero(self.active)

    # ------------------------------------------------------------------ motion

    def seek(self, slot: np.ndarray | int, goal: np.ndarray, speed: np.ndarray | float) -> None:
        """Set desired velocities towards ``goal``, slowing within 0.5 m of it."""
        delta = np.atleast_2d(goal) - self.pos[slot]
        dist = np.linalg.norm(delta, axis=-1, keepdims=True)
        scale = np.minimum(1.0, dist / 0.5) * np.atleast_1d(speed)[..., None]
        self.v_des[slot] = np.where(dist > 1e-9, delta / np.maximum(dist, 1e-9) * scale, 0.0)

    def step(self) -> None:
        """Advance the world by one ``dt``."""
        self.director.update(self, self.t)
        idx = self.slots
        if len(idx):
            pos, vel = self.pos[idx], self.vel[idx]
            force = (self.v_des[idx] - vel) / self.RELAX_S
            force += self._person_forces(pos, self.radius[idx])
            force += self._wall_forces(pos, self.radius[idx])
            vel = vel + force * self.dt
            speed = np.linalg.norm(vel, axis=1, keepdims=True)
            vel = np.where(speed > self.MAX_SPEED, vel / speed * self.MAX_SPEED, vel)
            pos = pos + vel * self.dt
            pos, vel = self._constrain(pos, vel, self.radius[idx])
            self.pos[idx], self.vel[idx] = pos, vel
            walking = np.einsum("ij,ij->i", vel, vel) >= self.HEADING_MIN_SPEED**2
            self.heading[idx[walking]] = np.arctan2(vel[walking, 1], vel[walking, 0])
        self.t += self.dt
        self._prev, self._cur = self._cur, self.snapshot()

    def _person_forces(self, pos: np.ndarray, radius: np.ndarray) -> np.ndarray:
        n = len(pos)
        if n < 2:
            return np.zeros_like(pos)
        delta = pos[:, None, :] - pos[None, :, :]
        dist = np.linalg.norm(delta, axis=2)
        np.fill_diagonal(dist, np.inf)
        reach = radius[:, None] + radius[None, :]
        mag = self.PERSON_A * np.exp((reach - dist) / self.PERSON_B)
        mag[dist > reach + 1.0] = 0.0
        unit = delta / np.maximum(dist, 1e-6)[:, :, None]
        return np.einsum("ij,ijk->ik", mag, unit)

    def _wall_forces(self, pos: np.ndarray, radius: np.ndarray) -> np.ndarray:
        force = np.zeros_like(pos)
        r = self.room
        for axis, lo, hi in ((0, 0.0, r.width), (1, 0.0, r.depth)):
            d_lo = pos[:, axis] - lo
            d_hi = hi - pos[:, axis]
            force[:, axis] += self.WALL_A * np.exp((radius - d_lo) / self.WALL_B)
            force[:, axis] -= self.WALL_A * np.exp((radius - d_hi) / self.WALL_B)
        for o in r.obstacles:
            nearest = np.column_stack(
                [np.clip(pos[:, 0], o.x0, o.x1), np.clip(pos[:, 1], o.y0, o.y1)]
            )
            delta = pos - nearest
            dist = np.linalg.norm(delta, axis=1)
            mag = self.WALL_A * np.exp((radius - dist) / self.WALL_B)
            mag[dist > radius + 1.0] = 0.0
            force += (mag / np.maximum(dist, 1e-6))[:, None] * delta
        return force

    def _constrain(
        self, pos: np.ndarray, vel: np.ndarray, radius: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        pos, vel = self._separate(pos, vel, radius)
        r = self.room
        lo = radius[:, None]
        hi = np.column_stack([r.width - radius, r.depth - radius])
        clipped = np.clip(pos, lo, hi)
        vel = np.where(clipped != pos, 0.0, vel)
        pos = clipped
        for o in r.obstacles:
            inside = (
                (pos[:, 0] > o.x0 - radius)
                & (pos[:, 0] < o.x1 + radius)
                & (pos[:, 1] > o.y0 - radius)
                & (pos[:, 1] < o.y1 + radius)
            )
            for i in np.flatnonzero(inside):
                # push out through the nearest face
                exits = np.array(
                    [
                        pos[i, 0] - (o.x0 - radius[i]),
                        (o.x1 + radius[i]) - pos[i, 0],
                        pos[i, 1] - (o.y0 - radius[i]),
                        (o.y1 + radius[i]) - pos[i, 1],
                    ]
                )
                face = int(np.argmin(exits))
                axis, sign = _FACES[face]
                pos[i, axis] += sign * exits[face]
                vel[i, axis] = 0.0
        return pos, vel

    MIN_GAP = 0.9
    """People never stand closer than this fraction of the sum of their radii."""

    def _separate(
        self, pos: np.ndarray, vel: np.ndarray, radius: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Push apart people whose bodies overlap, and stop them walking into each other."""
        if len(pos) < 2:
            return pos, vel
        delta = pos[:, None, :] - pos[None, :, :]
        dist = np.linalg.norm(delta, axis=2)
        reach = self.MIN_GAP * (radius[:, None] + radius[None, :])
        rows, cols = np.nonzero(np.triu(dist < reach, k=1))
        for i, j in zip(rows.tolist(), cols.tolist(), strict=True):
            d = pos[i] - pos[j]
            gap = float(np.hypot(d[0], d[1]))
            need = self.MIN_GAP * (radius[i] + radius[j])
            if gap >= need:
                continue  # already resolved by an earlier push this step
            n = d / gap if gap > 1e-9 else np.array([1.0, 0.0])
            shift = 0.5 * (need - gap) * n
            pos[i] += shift
            pos[j] -= shift
            closing = float(np.dot(vel[i] - vel[j], n))
            if closing < 0:  # moving towards each other: remove that part
                vel[i] -= 0.5 * closing * n
                vel[j] += 0.5 * closing * n
        return pos, vel

    # ---------------------------------------------------------------- sampling

    def snapshot(self) -> Snapshot:
        """Everyone's state now."""
        idx = self.slots
        return Snapshot(
            t=self.t,
            ids=self.ids[idx].copy(),
            kinds=self.kind[idx].copy(),
            pos=self.pos[idx].copy(),
            vel=self.vel[idx].copy(),
            height=self.height[idx].copy(),
            radius=self.radius[idx].copy(),
            top_hue=self.top_hue[idx].copy(),
            bottom_hue=self.bottom_hue[idx].copy(),
            top_saturation=self.top_saturation[idx].copy(),
            top_value=self.top_value[idx].copy(),
            bottom_saturation=self.bottom_saturation[idx].copy(),
            bottom_value=self.bottom_value[idx].copy(),
            heading=self.heading[idx].copy(),
        )

    def advance_to(self, t: float) -> None:
        """Step until the world's time reaches ``t``."""
        while self.t < t - 1e-12:
            self.step()

    def state_at(self, t: float) -> Snapshot:
        """Everyone's state at ``t``, which must lie within the last step.

        People present at both ends of the step are interpolated; people who entered
        during the step appear at their entry point, people who left are gone.
        """
        self.advance_to(t)
        prev, cur = self._prev, self._cur
        if t >= cur.t - 1e-12 or cur.t <= prev.t:
            return cur
        if t < prev.t - 1e-9:
            raise ValueError(f"state_at({t:.4f}): the world is already at {cur.t:.4f}")
        w = (t - prev.t) / (cur.t - prev.t)
        common, i_prev, i_cur = np.intersect1d(prev.ids, cur.ids, return_indices=True)
        pos = cur.pos.copy()
        vel = cur.vel.copy()
        pos[i_cur] = (1 - w) * prev.pos[i_prev] + w * cur.pos[i_cur]
        vel[i_cur] = (1 - w) * prev.vel[i_prev] + w * cur.vel[i_cur]
        del common
        return Snapshot(
            t=t,
            ids=cur.ids,
            kinds=cur.kinds,
            pos=pos,
            vel=vel,
            height=cur.height,
            radius=cur.radius,
            top_hue=cur.top_hue,
            bottom_hue=cur.bottom_hue,
            top_saturation=cur.top_saturation,
            top_value=cur.top_value,
            bottom_saturation=cur.bottom_saturation,
            bottom_value=cur.bottom_value,
            heading=cur.heading,
        )
