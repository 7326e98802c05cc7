"""Directors: what the people of a scenario do, step by step.

A director (:class:`~openptrack_py.sim.world.Director`) places people when the world starts
and steers them every step: :class:`WaypointDirector` (walk to random goals, pause),
:class:`ShuttleDirector` (walk fixed routes back and forth), :class:`CircleGameDirector`
(the childcare papers' drum game: a teacher leads children around a circle, stopping and
running with the drum), :class:`VisitorDirector` (visitors come in by the doors, look at
works, leave) and :class:`ReentryDirector` (the same people walk about, leave by a door
and come back later, as themselves).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from openptrack_py.sim.people import PersonSpec, random_person
from openptrack_py.sim.walking import door_inside, steer_around
from openptrack_py.sim.world import Room, World

Dresser = Callable[[PersonSpec, int], PersonSpec]
"""``dress(spec, index) -> spec``: a scenario's clothes for the ``index``-th person placed."""


@dataclass
class WaypointDirector:
    """People walk to random goals, pause, pick another goal.

    Parameters
    ----------
    count : int
        Number of people (all present from the start).
    sample_goal : callable
        ``sample_goal(rng) -> (x, y)``.
    pause_s : tuple of float
        Uniform range of the pause at each goal.
    kind_of : callable
        ``kind_of(index) -> "adult" | "child"``.
    rng : numpy.random.Generator
        Randomness.
    """

    count: int
    sample_goal: Callable[[np.random.Generator], np.ndarray]
    pause_s: tuple[float, float]
    rng: np.random.Generator
    kind_of: Callable[[int], str] = field(default=lambda _i: "adult")
    goals: dict[int, np.ndarray] = field(default_factory=dict)
    resume_at: dict[int, float] = field(default_factory=dict)

    def start(self, world: World) -> None:
        """Place everyone at separate random points."""
        placed: list[np.ndarray] = []
        for i in range(self.count):
            for _ in range(200):
                p = self.sample_goal(self.rng)
                if all(np.linalg.norm(p - q) > 0.7 for q in placed):
                    break
            placed.append(p)
            slot = world.add_person(random_person(self.rng, self.kind_of(i)), p)  # type: ignore[arg-type]
            self.goals[slot] = self.sample_goal(self.rng)
            self.resume_at[slot] = float(self.rng.uniform(0.0, self.pause_s[1]))

    def update(self, world: World, t: float) -> None:
        """Walk towards goals; on arrival pause, then draw a new goal."""
        walking = []
        for slot in world.slots.tolist():
            if t < self.resume_at[slot]:
                world.v_des[slot] = 0.0
                continue
            goal = self.goals[slot]
            dx, dy = goal[0] - world.pos[slot, 0], goal[1] - world.pos[slot, 1]
            if dx * dx + dy * dy < 0.09:
                self.goals[slot] = self.sample_goal(self.rng)
                self.resume_at[slot] = t + float(self.rng.uniform(*self.pause_s))
                world.v_des[slot] = 0.0
                continue
            walking.append(slot)
        if walking:
            idx = np.array(walking)
            world.seek(idx, np.array([self.goals[s] for s in walking]), world.speed[idx])


@dataclass
class ShuttleDirector:
    """Each person loops through a fixed list of waypoints, pausing at each.

    Parameters
    ----------
    routes : list of list of (float, float)
        One route per person; the person starts at its first point.
    pause_s : float
        Pause at each waypoint.
    start_delay_s : list of float
        Per person, time before they start walking.
    rng : numpy.random.Generator
        Randomness (appearance and speed).
    """

    routes: list[list[tuple[float, float]]]
    pause_s: float
    start_delay_s: list[float]
    rng: np.random.Generator
    leg: dict[int, int] = field(default_factory=dict)
    resume_at: dict[int, float] = field(default_factory=dict)
    _route_of: dict[int, list[tuple[float, float]]] = field(default_factory=dict)

    def start(self, world: World) -> None:
        """Put each person at the start of their route."""
        for route, delay in zip(self.routes, self.start_delay_s, strict=True):
            slot = world.add_person(random_person(self.rng, "adult"), np.array(route[0]))
            self._route_of[slot] = route
            self.leg[slot] = 1 % len(route)
            self.resume_at[slot] = delay

    def update(self, world: World, t: float) -> None:
        """Walk the routes."""
        for slot in world.slots:
            slot = int(slot)
            route = self._route_of[slot]
            if t < self.resume_at[slot]:
                world.v_des[slot] = 0.0
                continue
            goal = np.array(route[self.leg[slot]])
            if np.linalg.norm(goal - world.pos[slot]) < 0.25:
                self.leg[slot] = (self.leg[slot] + 1) % len(route)
                self.resume_at[slot] = t + self.pause_s
                world.v_des[slot] = 0.0
                continue
            world.seek(slot, goal, world.speed[slot])


# Drum-game schedule: (start time in the cycle, angular speed of the group in rad/s).
_DRUM_CYCLE: list[tuple[float, float]] = [
    (0.0, 0.22),  # walk slowly, clockwise, in time with the drum
    (18.0, 0.0),  # the drum stops: everyone stops
    (22.0, 0.22),  # walk on
    (38.0, 0.0),  # explanation of the game, little movement
    (55.0, 0.62),  # run one lap
    (65.0, 0.0),  # stop
    (70.0, 0.85),  # faster rhythm, another lap
    (77.5, 0.0),  # stop
]
_DRUM_PERIOD_S = 85.0


@dataclass
class CircleGameDirector:
    """A teacher leads children around a circle, stopping and running with the drum.

    Parameters
    ----------
    centre : (float, float)
        Centre of the circle.
    radius : float
        Radius the children walk on.
    children : int
        Number of children.
    rng : numpy.random.Generator
        Randomness.
    dress : callable, optional
        Clothes for each person (index 0 the teacher, then the children), replacing the
        drawn ones; every draw of ``rng`` stays the same.
    """

    centre: tuple[float, float]
    radius: float
    children: int
    rng: np.random.Generator
    dress: Dresser | None = None
    _phase: np.ndarray = field(init=False)
    _times: np.ndarray = field(init=False)
    _angle0: dict[int, float] = field(default_factory=dict)
    _delay: dict[int, float] = field(default_factory=dict)
    _radius: dict[int, float] = field(default_factory=dict)
    _teacher: int = -1

    def __post_init__(self) -> None:
        # Group progress Phi(t) (radians travelled clockwise) on a fine grid, one cycle.
        dt = 0.05
        self._times = np.arange(0.0, _DRUM_PERIOD_S + dt, dt)
        starts = np.array([s for s, _ in _DRUM_CYCLE])
        speeds = np.array([w for _, w in _DRUM_CYCLE])
        omega = speeds[np.searchsorted(starts, self._times, side="right") - 1]
        # smooth starts and stops over ~1 s (people accelerate, they do not jump)
        kernel = np.ones(int(1.0 / dt)) / int(1.0 / dt)
        omega = np.convolve(omega, kernel, mode="same")
        self._phase = np.concatenate([[0.0], np.cumsum(omega[:-1] * dt)])

    def progress(self, t: float) -> float:
        """Radians the group has travelled clockwise by time ``t``."""
        if t <= 0.0:
            return 0.0
        cycles, rest = divmod(t, _DRUM_PERIOD_S)
        return float(cycles * self._phase[-1] + np.interp(rest, self._times, self._phase))

    def start(self, world: World) -> None:
        """Children spread evenly on the circle, the teacher just ahead of them."""
        c = np.array(self.centre)
        teacher = world.add_person(self._dressed(random_person(self.rng, "adult"), 0), c)
        self._teacher = teacher
        self._angle0[teacher] = math.pi / 2 + 0.35
        self._delay[teacher] = 0.0
        self._radius[teacher] = self.radius + 0.45
        world.pos[teacher] = c + self._radius[teacher] * np.array(
            [math.cos(self._angle0[teacher]), math.sin(self._angle0[teacher])]
        )
        spacing = 2 * math.pi / self.children
        for i in range(self.children):
            angle = math.pi / 2 - i * spacing + float(self.rng.uniform(-0.1, 0.1)) * spacing
            r = self.radius + float(self.rng.uniform(-0.15, 0.15))
            slot = world.add_person(
                self._dressed(random_person(self.rng, "child"), i + 1),
                c + r * np.array([math.cos(angle), math.sin(angle)]),
            )
            self._angle0[slot] = angle
            self._radius[slot] = r
            # children react to the drum with a short, individual delay
            self._delay[slot] = float(self.rng.uniform(0.3, 1.5))

    def _dressed(self, spec: PersonSpec, index: int) -> PersonSpec:
        return spec if self.dress is None else self.dress(spec, index)

    def update(self, world: World, t: float) -> None:
        """Steer everyone towards their moving place on the circle."""
        c = np.array(self.centre)
        explaining = 38.0 <= t % _DRUM_PERIOD_S < 55.0
        for slot in world.slots:
            slot = int(slot)
            tau = t - self._delay[slot]
            angle = self._angle0[slot] - self.progress(tau)
            r = self._radius[slot]
            if slot == self._teacher and explaining:
                target = c + np.array([0.0, 0.4])  # the teacher steps into the middle
            else:
                target = c + r * np.array([math.cos(angle), math.sin(angle)])
            # feed-forward along the circle plus a pull onto the target
            omega = (self.progress(tau + 0.1) - self.progress(tau)) / 0.1
            tangent = r * omega * np.array([math.sin(angle), -math.cos(angle)])
            sway = 0.05 * np.array([math.sin(1.7 * t + slot), math.cos(1.3 * t + 2 * slot)])
            v = tangent + 1.5 * (target - world.pos[slot]) + sway
            top = 2.2 if world.kind[slot] == "child" else 2.5
            speed = float(np.linalg.norm(v))
            world.v_des[slot] = v if speed <= top else v / speed * top


@dataclass
class VisitorDirector:
    """Visitors enter through doors, look at a few works, and leave.

    Parameters
    ----------
    room : Room
        The space (its ``doors`` are the entrances and exits).
    spots : list of (float, float)
        Where the works are; visitors stop near them.
    arrival_interval_s : float
        Mean time between arrivals (Poisson process).
    max_present : int
        Nobody enters while this many are inside.
    initial : int
        Visitors already inside at the start.
    child_fraction : float
        Share of visitors who are children.
    rng : numpy.random.Generator
        Randomness.
    """

    room: Room
    spots: list[tuple[float, float]]
    arrival_interval_s: float
    max_present: int
    initial: int
    child_fraction: float
    rng: np.random.Generator
    _plans: dict[int, list[np.ndarray]] = field(default_factory=dict)
    _dwell_until: dict[int, float] = field(default_factory=dict)
    _leaving: dict[int, bool] = field(default_factory=dict)
    _next_arrival: float = 0.0

    def _plan(self) -> list[np.ndarray]:
        count = int(self.rng.integers(2, 5))
        chosen = self.rng.choice(len(self.spots), size=min(count, len(self.spots)), replace=False)
        return [np.array(self.spots[i]) + self.rng.normal(0, 0.25, 2) for i in chosen]

    def _door_inside(self, door: tuple[float, float]) -> np.ndarray:
        return door_inside(self.room, door)

    def _admit(self, world: World, where: np.ndarray, t: float) -> None:
        kind = "child" if self.rng.random() < self.child_fraction else "adult"
        slot = world.add_person(random_person(self.rng, kind), where)  # type: ignore[arg-type]
        self._plans[slot] = self._plan()
        self._dwell_until[slot] = t
        self._leaving[slot] = False

    def start(self, world: World) -> None:
        """A few visitors are already looking at works."""
        for _ in range(self.initial):
            self._admit(world, self.room.random_free_point(self.rng, 0.6), 0.0)
        self._next_arrival = float(self.rng.exponential(self.arrival_interval_s))

    def update(self, world: World, t: float) -> None:
        """Admit arrivals, walk visitors through their plans, remove those who left."""
        present = len(world.slots)
        if t >= self._next_arrival:
            if present < self.max_present:
                door = self.room.doors[int(self.rng.integers(len(self.room.doors)))]
                entry = self._door_inside(door)
                crowded = any(np.linalg.norm(world.pos[s] - entry) < 0.6 for s in world.slots)
                if not crowded:
                    self._admit(world, entry, t)
            self._next_arrival = t + float(self.rng.exponential(self.arrival_interval_s))
        for slot in world.slots:
            slot = int(slot)
            plan = self._plans[slot]
            if t < self._dwell_until[slot]:
                world.v_des[slot] = 0.05 * np.array([math.sin(0.9 * t + slot), 0.0])
                continue
            if not plan:
                if not self._leaving[slot]:
                    self._leaving[slot] = True
                    door = self.room.doors[int(self.rng.integers(len(self.room.doors)))]
                    plan.append(self._door_inside(door))
                else:
                    world.remove_person(slot)
                    continue
            goal = plan[0]
            if np.linalg.norm(goal - world.pos[slot]) < 0.35:
                plan.pop(0)
                if not self._leaving[slot]:
                    self._dwell_until[slot] = t + float(self.rng.uniform(3.0, 12.0))
                world.v_des[slot] = 0.0
                continue
            world.seek(slot, goal, world.speed[slot] * 0.8)


@dataclass
class ReentryDirector:
    """The same people walk about, leave by a door, stay away a while and come back.

    Everyone is inside at the start. Each stay, a person walks to a few goals (pausing at
    each), then to a door, where they leave the room; after a time drawn uniformly from
    ``away_s`` they come back through a door (any door, drawn again) with the same
    ground-truth id and the same clothes.

    Parameters
    ----------
    room : Room
        The room (its ``doors`` are the ways out and in).
    count : int
        Number of people.
    sample_goal : callable
        ``sample_goal(rng) -> (x, y)``.
    rng : numpy.random.Generator
        Randomness.
    away_s : tuple of float
        Uniform range of the time spent outside, seconds.
    goals_per_stay : tuple of int
        Inclusive range of the number of goals a person visits before leaving.
    pause_s : tuple of float
        Uniform range of the pause at each goal, seconds.
    """

    room: Room
    count: int
    sample_goal: Callable[[np.random.Generator], np.ndarray]
    rng: np.random.Generator
    away_s: tuple[float, float] = (10.0, 120.0)
    goals_per_stay: tuple[int, int] = (1, 3)
    pause_s: tuple[float, float] = (0.5, 3.0)
    _specs: dict[int, PersonSpec] = field(default_factory=dict)
    _plans: dict[int, list[np.ndarray]] = field(default_factory=dict)
    _leaving: dict[int, bool] = field(default_factory=dict)
    _resume_at: dict[int, float] = field(default_factory=dict)
    _back_at: dict[int, float] = field(default_factory=dict)

    def _stay(self, person: int, t: float) -> None:
        """Plan a new stay in the room for ``person`` from time ``t``."""
        lo, hi = self.goals_per_stay
        goals = int(self.rng.integers(lo, hi + 1))
        self._plans[person] = [self.sample_goal(self.rng) for _ in range(goals)]
        self._leaving[person] = False
        self._resume_at[person] = t

    def _door(self) -> np.ndarray:
        doors = self.room.doors
        return door_inside(self.room, doors[int(self.rng.integers(len(doors)))])

    def start(self, world: World) -> None:
        """Everyone starts inside, at separate random points."""
        placed: list[np.ndarray] = []
        for _ in range(self.count):
            for _ in range(200):
                p = self.sample_goal(self.rng)
                if all(np.linalg.norm(p - q) > 0.7 for q in placed):
                    break
            placed.append(p)
            spec = random_person(self.rng, "adult")
            person = int(world.ids[world.add_person(spec, p)])
            self._specs[person] = spec
            self._stay(person, float(self.rng.uniform(0.0, self.pause_s[1])))

    def update(self, world: World, t: float) -> None:
        """Bring back those whose time outside is over, walk the others, let them leave."""
        for person, back in sorted(self._back_at.items()):
            if t < back:
                continue
            entry = self._door()
            if any(np.linalg.norm(world.pos[s] - entry) < 0.6 for s in world.slots):
                self._back_at[person] = t + 0.5  # the doorway is busy: a moment later
                continue
            del self._back_at[person]
            world.add_person(self._specs[person], entry, person_id=person)
            self._stay(person, t)
        for slot in world.slots.tolist():
            person = int(world.ids[slot])
            plan = self._plans[person]
            if t < self._resume_at[person]:
                world.v_des[slot] = 0.0
                continue
            if not plan:  # every goal visited: make for a door
                self._leaving[person] = True
                plan.append(self._door())
            if np.linalg.norm(plan[0] - world.pos[slot]) < 0.35:
                plan.pop(0)
                world.v_des[slot] = 0.0
                if self._leaving[person]:
                    world.remove_person(slot)
                    self._back_at[person] = t + float(self.rng.uniform(*self.away_s))
                else:
                    self._resume_at[person] = t + float(self.rng.uniform(*self.pause_s))
                continue
            way = steer_around(self.room, world.pos[slot], plan[0], world.radius[slot])
            world.seek(slot, way, world.speed[slot])
