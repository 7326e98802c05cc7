"""Named, seeded scenarios that mirror the sequences of the seed papers.

==============  ==========================================================================
``crowd``       7 adults walking to random points 1-9 m from the first sensor, pausing;
                10 x 10 m room, 3 Kinect v2 (OpenPTrack's "Crowd" sequence, with a network)
``distance``    2 people walking straight out to 10 m from one sensor and back
                (OpenPTrack's "Distance")
``occlusions``  2 people walking loops 1-8 m from one sensor, behind tall cabinets
                (OpenPTrack's "Occlusions")
``classroom``   a teacher and 15-20 children (0.8-1.2 m tall) playing the drum game: walk
                slowly clockwise in a circle, stop, explanation, run a lap, faster again
                (the child-care papers' nursery class)
``installation`` visitors entering an art space by its doors, looking at works, leaving
``stress``      120 people in a 30 x 16 m hall seen by 10 sensors
==============  ==========================================================================

The same name, seed and options always give the same people, paths and sensor noise.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from openptrack_py.config import Pose, SensorConfig
from openptrack_py.errors import ConfigError
from openptrack_py.sensor_types import SENSOR_TYPES
from openptrack_py.sim.sensors import SensorModel, SensorSpec
from openptrack_py.sim.world import Director, Obstacle, Room, World, random_person


@dataclass(frozen=True)
class Scenario:
    """Everything needed to run one simulation.

    Parameters
    ----------
    name : str
        Scenario name.
    seed : int
        Random seed.
    duration_s : float or None
        Length of the run; ``None`` runs forever.
    room : Room
        The room.
    sensors : tuple of SensorSpec
        The virtual sensors.
    make_director : callable
        Builds the script from the world's random generator.
    description : str
        One line about what happens.
    """

    name: str
    seed: int
    duration_s: float | None
    room: Room
    sensors: tuple[SensorSpec, ...]
    make_director: Callable[[np.random.Generator], Director]
    description: str = ""


# ------------------------------------------------------------------------ directors


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
    """

    centre: tuple[float, float]
    radius: float
    children: int
    rng: np.random.Generator
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
        teacher = world.add_person(random_person(self.rng, "adult"), c)
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
                random_person(self.rng, "child"),
                c + r * np.array([math.cos(angle), math.sin(angle)]),
            )
            self._angle0[slot] = angle
            self._radius[slot] = r
            # children react to the drum with a short, individual delay
            self._delay[slot] = float(self.rng.uniform(0.3, 1.5))

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
        x, y = door
        return np.array(
            [np.clip(x, 0.3, self.room.width - 0.3), np.clip(y, 0.3, self.room.depth - 0.3)]
        )

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


# ------------------------------------------------------------------------ scenarios


def _sensor(
    sensor_id: str, x: float, y: float, z: float, yaw: float, pitch: float, kind: str = "kinect2"
) -> SensorConfig:
    return SensorConfig(
        id=sensor_id,
        type=kind,  # type: ignore[arg-type]
        pose=Pose(x=x, y=y, z=z, yaw_deg=yaw, pitch_deg=pitch),
    )


def _coverage(room: Room, sensors: Sequence[SensorConfig]) -> Callable[[np.ndarray], bool]:
    """Whether an adult standing at a point, and 0.4 m around it, is in some sensor's view.

    Scenarios use their own designed sensor layout for this, so people's paths do not
    depend on which sensors a network file chooses to simulate.
    """
    models = [
        SensorModel(SensorSpec.from_config(cfg), room, np.random.default_rng(0)) for cfg in sensors
    ]
    ring = 0.4 * np.array([(0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)], dtype=float)

    def covered(xy: np.ndarray) -> bool:
        points = xy[None, :] + ring
        heights = np.full(len(points), 1.75)
        seen = np.zeros(len(points), dtype=bool)
        for model in models:
            seen |= model.covers(points, heights)
        return bool(seen.all())

    return covered


def _goal_sampler(
    room: Room,
    sensors: Sequence[SensorConfig],
    centre: np.ndarray | None = None,
    ring: tuple[float, float] = (0.0, np.inf),
) -> Callable[[np.random.Generator], np.ndarray]:
    """Random free, covered points (optionally at a distance in ``ring`` from ``centre``)."""
    covered = _coverage(room, sensors)

    def sample(rng: np.random.Generator) -> np.ndarray:
        for _ in range(2000):
            p = room.random_free_point(rng, 0.5)
            near = centre is None or ring[0] <= np.linalg.norm(p - centre) <= ring[1]
            if near and covered(p):
                return p
        raise RuntimeError("scenario: no covered free floor to walk to")

    return sample


def _crowd(seed: int, rng: np.random.Generator, people: int = 7) -> tuple:
    room = Room(10.0, 10.0)
    sensors = [
        _sensor("k2_a", 0.2, 0.2, 2.6, 45.0, 22.0),
        _sensor("k2_b", 9.8, 0.2, 2.6, 135.0, 22.0),
        _sensor("k2_c", 5.0, 9.8, 2.6, -90.0, 22.0),
    ]
    sampler = _goal_sampler(room, sensors, np.array([0.2, 0.2]), (1.0, 9.0))

    def director(r: np.random.Generator) -> Director:
        return WaypointDirector(people, sampler, (0.0, 2.0), r)

    return room, sensors, director, 120.0


def _distance(seed: int, rng: np.random.Generator) -> tuple:
    room = Room(12.0, 4.0)
    sensors = [_sensor("k2_a", 0.15, 2.0, 1.9, 0.0, 8.0)]
    routes = [[(1.0, 1.4), (10.5, 1.4)], [(1.2, 2.6), (10.5, 2.6)]]

    def director(r: np.random.Generator) -> Director:
        return ShuttleDirector(routes, pause_s=1.0, start_delay_s=[0.0, 4.0], rng=r)

    return room, sensors, director, 90.0


def _occlusions(seed: int, rng: np.random.Generator) -> tuple:
    room = Room(
        10.0,
        8.0,
        obstacles=(
            Obstacle("cabinet_a", 3.5, 2.6, 4.1, 3.8, 1.95),
            Obstacle("cabinet_b", 5.5, 4.6, 6.1, 5.8, 1.95),
            Obstacle("table", 2.0, 5.2, 3.2, 6.0, 0.75),
        ),
    )
    sensors = [_sensor("k2_a", 0.2, 4.0, 2.2, 0.0, 12.0)]
    routes = [
        [(1.5, 4.5), (4.8, 2.2), (8.0, 3.2), (4.8, 3.2)],
        [(8.0, 5.0), (6.8, 5.2), (2.0, 4.6), (6.8, 5.2)],
    ]

    def director(r: np.random.Generator) -> Director:
        return ShuttleDirector(routes, pause_s=0.8, start_delay_s=[0.0, 2.0], rng=r)

    return room, sensors, director, 90.0


def _classroom(seed: int, rng: np.random.Generator, children: int | None = None) -> tuple:
    room = Room(8.0, 7.0, obstacles=(Obstacle("piano", 6.6, 0.1, 7.9, 0.8, 1.2),))
    sensors = [
        _sensor("front", 4.0, 0.15, 1.1, 90.0, 2.0),
        _sensor("slant_l", 0.25, 6.75, 2.8, -45.0, 32.0),
        _sensor("slant_r", 7.75, 6.75, 2.8, -135.0, 32.0),
    ]
    count = int(children if children is not None else rng.integers(15, 21))

    def director(r: np.random.Generator) -> Director:
        return CircleGameDirector((4.0, 3.6), 2.2, count, r)

    return room, sensors, director, 170.0


INSTALLATION_SENSORS = (
    ("k2_a", 0.3, 0.3, 2.7, 38.0, 28.0),
    ("k2_b", 7.7, 0.3, 2.7, 142.0, 28.0),
    ("k2_c", 4.0, 5.7, 2.7, -90.0, 30.0),
)


def _installation(seed: int, rng: np.random.Generator) -> tuple:
    room = Room(
        8.0,
        6.0,
        obstacles=(Obstacle("plinth", 3.6, 2.6, 4.4, 3.4, 1.0),),
        doors=((0.0, 3.0), (8.0, 1.2)),
    )
    sensors = [_sensor(*s) for s in INSTALLATION_SENSORS]
    spots = [(1.2, 0.8), (4.0, 0.8), (6.8, 4.8), (4.0, 5.0), (1.2, 5.0), (6.5, 2.2), (3.0, 2.2)]

    def director(r: np.random.Generator) -> Director:
        return VisitorDirector(room, spots, 7.0, 8, 2, 0.2, r)

    return room, sensors, director, 180.0


def _stress(seed: int, rng: np.random.Generator, people: int = 120) -> tuple:
    # A 30 x 16 m hall: two rows of sensors on the long walls and one on each end wall,
    # so that every point of the floor is within Kinect v2's reliable 8 m of a sensor.
    room = Room(30.0, 16.0)
    sensors = [_sensor(f"s{i}", x, 0.3, 3.0, 90.0, 24.0) for i, x in enumerate((3, 10, 17, 24))]
    sensors += [
        _sensor(f"s{i + 4}", x, 15.7, 3.0, -90.0, 24.0) for i, x in enumerate((6, 13, 20, 27))
    ]
    sensors += [
        _sensor("s8", 0.3, 8.0, 3.0, 0.0, 20.0),
        _sensor("s9", 29.7, 8.0, 3.0, 180.0, 20.0),
    ]

    sample = _goal_sampler(room, sensors)

    def director(r: np.random.Generator) -> Director:
        return WaypointDirector(people, sample, (0.0, 3.0), r)

    return room, sensors, director, 120.0


_BUILDERS: dict[str, tuple[Callable[..., tuple], str]] = {
    "crowd": (_crowd, "7 people moving randomly 1-9 m from a sensor; 3 Kinect v2"),
    "distance": (_distance, "2 people walking out to 10 m from one sensor and back"),
    "occlusions": (_occlusions, "2 people walking behind tall cabinets, 1-8 m from one sensor"),
    "classroom": (_classroom, "a teacher and 15-20 children playing the drum game in a circle"),
    "installation": (_installation, "visitors entering an art space, looking, leaving"),
    "stress": (_stress, "120 people in a 30 x 16 m hall, 10 sensors"),
}
SCENARIO_NAMES = tuple(_BUILDERS)
_OPTION_MINIMUM = {"people": 0, "children": 1}  # an empty hall is fine, a class is not


def scenario_options(name: str) -> list[str]:
    """Names of the options (keyword parameters) a scenario accepts."""
    builder = _BUILDERS[name][0]
    params = list(inspect.signature(builder).parameters.values())[2:]  # after seed, rng
    return [p.name for p in params]


def describe_scenarios() -> dict[str, str]:
    """Scenario name to one-line description."""
    return {name: text for name, (_, text) in _BUILDERS.items()}


def build_scenario(
    name: str,
    seed: int = 0,
    duration_s: float | None = -1.0,
    sensors: Sequence[SensorConfig] | None = None,
    **options: int,
) -> Scenario:
    """Build a named scenario.

    Parameters
    ----------
    name : str
        One of :data:`SCENARIO_NAMES`.
    seed : int
        Random seed.
    duration_s : float or None
        Run length; the scenario's own default when negative; ``None`` for no end.
    sensors : sequence of SensorConfig, optional
        Replace the scenario's sensors (e.g. those of a network file).
    **options
        Scenario parameters: ``people`` (crowd, stress), ``children`` (classroom).

    Raises
    ------
    ConfigError
        For an unknown scenario or option.
    """
    if name not in _BUILDERS:
        raise ConfigError(f"scenario: unknown {name!r} (allowed: {', '.join(SCENARIO_NAMES)})")
    builder, description = _BUILDERS[name]
    allowed = scenario_options(name)
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise ConfigError(
            f"scenario {name}: unknown option {', '.join(unknown)} "
            f"(allowed: {', '.join(allowed) or 'none'})"
        )
    for key, value in options.items():
        least = _OPTION_MINIMUM.get(key, 1)
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            raise ConfigError(
                f"scenario {name}: {key} must be an integer >= {least} (received {value!r})"
            )
    root = np.random.SeedSequence(seed)
    layout_rng = np.random.default_rng(root.spawn(1)[0])
    room, default_sensors, make_director, default_duration = builder(seed, layout_rng, **options)
    chosen = list(sensors) if sensors else default_sensors
    phase_rng = np.random.default_rng([seed, 7])
    specs = []
    for cfg in chosen:
        if cfg.source != "sim":
            continue
        rate = cfg.rate_hz or SENSOR_TYPES[cfg.type].rate_hz
        specs.append(SensorSpec.from_config(cfg, phase_s=float(phase_rng.uniform(0, 1.0 / rate))))
    if duration_s is not None and duration_s < 0:
        duration_s = default_duration
    return Scenario(
        name=name,
        seed=seed,
        duration_s=duration_s,
        room=room,
        sensors=tuple(specs),
        make_director=make_director,
        description=description,
    )


def scenario_world(scenario: Scenario, dt: float = 0.04) -> World:
    """The scenario's world, seeded as :class:`Simulator` seeds it.

    Every process that simulates part of a scenario builds its world with this, so they
    all agree on where everybody is.
    """
    world_seq, _ = np.random.SeedSequence(scenario.seed).spawn(2)
    rng = np.random.default_rng(world_seq)
    return World(scenario.room, scenario.make_director(rng), rng, dt=dt)
