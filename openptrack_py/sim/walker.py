"""A person walking through a room to calibrate its sensors.

What a person is told when calibrating from a walk (Munaro et al., OpenPTrack, §4.3;
Zhang et al., children behavior tracking, §2.2): walk from point to point through the
whole space, preferably where two sensors or more see you, pausing now and then.
:class:`CalibrationWalker` is that person as a scenario director; :func:`walk_goals`
draws the points.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from openptrack_py.sim.people import random_person
from openptrack_py.sim.visibility import SensorView
from openptrack_py.sim.walking import steer_around
from openptrack_py.sim.world import Room, World

__all__ = ["CalibrationWalker", "walk_goals"]


def walk_goals(
    room: Room, views: Sequence[SensorView], overlap_preference: float
) -> Callable[[np.random.Generator], np.ndarray]:
    """Random free points the walker is seen at (by two sensors or more, preferably)."""
    ring = 0.4 * np.array([(0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)], dtype=float)

    def seen_by(xy: np.ndarray) -> int:
        points = xy[None, :] + ring
        heights = np.full(len(points), 1.75)
        return sum(bool(v.covers(points, heights).all()) for v in views)

    def sample(rng: np.random.Generator) -> np.ndarray:
        want = 2 if len(views) > 1 and rng.random() < overlap_preference else 1
        fallback = None
        for _ in range(2000):
            p = room.random_free_point(rng, 0.5)
            count = seen_by(p)
            if count >= want:
                return p
            if count >= 1 and fallback is None:
                fallback = p
        if fallback is None:
            raise RuntimeError("walk: no free floor in any sensor's view")
        return fallback

    return sample


@dataclass
class CalibrationWalker:
    """One adult walking from goal to goal, round the furniture, pausing at each goal.

    A goal not reached within ``give_up_s`` (blocked by furniture or a wall) is
    replaced by a new one, so the walker never stands pinned against an obstacle.

    Parameters
    ----------
    sample_goal : callable
        ``sample_goal(rng) -> (x, y)``.
    pause_s : tuple of float
        Range of the pause at each goal, seconds.
    rng : numpy.random.Generator
        Randomness.
    give_up_s : float
        Time allowed to reach a goal.
    """

    sample_goal: Callable[[np.random.Generator], np.ndarray]
    pause_s: tuple[float, float]
    rng: np.random.Generator
    give_up_s: float = 12.0
    slot: int = -1
    goal: np.ndarray = field(default_factory=lambda: np.zeros(2))
    resume_at: float = 0.0
    deadline: float = 0.0

    def start(self, world: World) -> None:
        """Place the walker at a first goal and pick the next."""
        self.slot = world.add_person(random_person(self.rng, "adult"), self.sample_goal(self.rng))
        self._next_goal(float(self.rng.uniform(*self.pause_s)))

    def _next_goal(self, now: float) -> None:
        self.goal = self.sample_goal(self.rng)
        self.resume_at = now
        self.deadline = now + self.give_up_s

    def update(self, world: World, t: float) -> None:
        """Walk towards the goal (round furniture); on arrival pause, then go on."""
        slot = self.slot
        if t < self.resume_at:
            world.v_des[slot] = 0.0
            return
        pos = world.pos[slot]
        if float(np.linalg.norm(self.goal - pos)) < 0.3 or t > self.deadline:
            self._next_goal(t + float(self.rng.uniform(*self.pause_s)))
            world.v_des[slot] = 0.0
            return
        way = steer_around(world.room, pos, self.goal, float(world.radius[slot]))
        world.seek(slot, way, world.speed[slot])
