"""Named, seeded scenarios after the OpenPTrack paper's sequences and the childcare class.

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
``reentry``     6 adults in the art space (3 Kinect v2, 3 doors) who walk about, leave by a
                door, stay out 10-120 s and come back by a door as themselves (same
                ground-truth id, same clothes): re-identification after absences
``uniforms``    the classroom (same children, same paths as ``classroom`` with the same
                seed) with everyone, teacher included, in one of two school uniforms
                (navy over grey, white over navy): colour cannot tell people apart
==============  ==========================================================================

People wear clothes drawn from realistic palettes (:mod:`~openptrack_py.sim.clothing`).

The same name, seed and options always give the same people, paths and sensor noise.
A noise profile (:mod:`~openptrack_py.sim.profiles`: ``ideal``, ``realistic``,
``harsh``) sets how far the sensors are from perfect; it never changes the people's paths.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from openptrack_py.calibration.files import SensorCalibration
from openptrack_py.config import Pose, SensorConfig
from openptrack_py.errors import ConfigError
from openptrack_py.sensor_types import SENSOR_TYPES
from openptrack_py.sim.clothing import SCHOOL_UNIFORMS
from openptrack_py.sim.directors import (
    CircleGameDirector,
    ReentryDirector,
    ShuttleDirector,
    VisitorDirector,
    WaypointDirector,
)
from openptrack_py.sim.false_positives import Decoy, place_decoys
from openptrack_py.sim.people import PersonSpec
from openptrack_py.sim.profiles import IDEAL, NoiseProfile, resolve_profile
from openptrack_py.sim.sensor_faults import draw_sensor_faults
from openptrack_py.sim.sensor_spec import SensorSpec
from openptrack_py.sim.visibility import SensorView
from openptrack_py.sim.walker import CalibrationWalker, walk_goals
from openptrack_py.sim.world import Director, Obstacle, Room, World


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
    profile : NoiseProfile
        The sensors' noise profile (its per-sensor draws are already in ``sensors``).
    decoys : tuple of Decoy
        Static false positives of the room under the profile.
    """

    name: str
    seed: int
    duration_s: float | None
    room: Room
    sensors: tuple[SensorSpec, ...]
    make_director: Callable[[np.random.Generator], Director]
    description: str = ""
    profile: NoiseProfile = IDEAL
    decoys: tuple[Decoy, ...] = ()


# ------------------------------------------------------------------------ directors


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
    models = [SensorView(SensorSpec.from_config(cfg), room) for cfg in sensors]
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


def _classroom_layout(
    rng: np.random.Generator, children: int | None
) -> tuple[Room, list[SensorConfig], int]:
    """The nursery room, its sensors and the number of children."""
    room = Room(8.0, 7.0, obstacles=(Obstacle("piano", 6.6, 0.1, 7.9, 0.8, 1.2),))
    sensors = [
        _sensor("front", 4.0, 0.15, 1.1, 90.0, 2.0),
        _sensor("slant_l", 0.25, 6.75, 2.8, -45.0, 32.0),
        _sensor("slant_r", 7.75, 6.75, 2.8, -135.0, 32.0),
    ]
    return room, sensors, int(children if children is not None else rng.integers(15, 21))


def _classroom(seed: int, rng: np.random.Generator, children: int | None = None) -> tuple:
    room, sensors, count = _classroom_layout(rng, children)

    def director(r: np.random.Generator) -> Director:
        return CircleGameDirector((4.0, 3.6), 2.2, count, r)

    return room, sensors, director, 170.0


def _uniforms(seed: int, rng: np.random.Generator, children: int | None = None) -> tuple:
    room, sensors, count = _classroom_layout(rng, children)
    # Who wears which uniform comes from a generator of its own: the people and their
    # paths are the classroom's.
    wears = np.random.default_rng([seed, 71]).integers(0, len(SCHOOL_UNIFORMS), count + 1)

    def dress(spec: PersonSpec, index: int) -> PersonSpec:
        return spec.wearing(*SCHOOL_UNIFORMS[int(wears[index])])

    def director(r: np.random.Generator) -> Director:
        return CircleGameDirector((4.0, 3.6), 2.2, count, r, dress=dress)

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


def _walk(seed: int, rng: np.random.Generator) -> tuple:
    """The installation's art space with one person walking through it to calibrate."""
    room, sensors, _, _ = _installation(seed, rng)
    views = [SensorView(SensorSpec.from_config(cfg), room) for cfg in sensors]
    goals = walk_goals(room, views, overlap_preference=1.0)

    def director(r: np.random.Generator) -> Director:
        return CalibrationWalker(goals, (0.0, 1.5), r)

    return room, sensors, director, 60.0


def _reentry(seed: int, rng: np.random.Generator, people: int = 6) -> tuple:
    room = Room(
        8.0,
        6.0,
        obstacles=(Obstacle("plinth", 3.6, 2.6, 4.4, 3.4, 1.0),),
        doors=((0.0, 3.0), (8.0, 1.2), (4.0, 0.0)),
    )
    sensors = [_sensor(*s) for s in INSTALLATION_SENSORS]
    sample = _goal_sampler(room, sensors)

    def director(r: np.random.Generator) -> Director:
        return ReentryDirector(room, people, sample, r)

    return room, sensors, director, 300.0


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


OVERHEAD_SENSORS = (
    # Ceiling sensors looking straight down over an entrance hall: the people-counting
    # layout. At 2.9 m a Kinect v2 sees a 4.1 x 3.3 m patch of floor; the three patches
    # overlap by about a metre.
    ("top_a", 1.8, 2.0, 2.9, 0.0, 90.0),
    ("top_b", 4.5, 2.0, 2.9, 0.0, 90.0),
    ("top_c", 7.2, 2.0, 2.9, 0.0, 90.0, "realsense"),
)


def _overhead(seed: int, rng: np.random.Generator) -> tuple:
    room = Room(9.0, 4.0, doors=((0.0, 2.0), (9.0, 2.0), (4.5, 4.0)))
    sensors = [_sensor(*s) for s in OVERHEAD_SENSORS]
    spots = [(2.0, 1.0), (4.5, 2.8), (7.0, 1.2), (3.2, 3.0), (6.0, 2.6)]

    def director(r: np.random.Generator) -> Director:
        return VisitorDirector(room, spots, 4.0, 6, 2, 0.1, r)

    return room, sensors, director, 120.0


CORRIDOR_CLUTTER = (
    # Free-standing poster boards and a bookshelf with tops at head height, a coat rack
    # and radiators: what a real corridor holds behind the people walking down it (the
    # tops of boards seen between people are a detector's classic false person).
    Obstacle("poster_board_1", 5.0, 0.35, 6.2, 0.38, 1.78),
    Obstacle("poster_board_2", 8.2, 2.8, 9.4, 2.83, 1.7),
    Obstacle("bookshelf", 6.6, 2.75, 7.6, 3.2, 1.65),
    Obstacle("coat_rack", 10.6, 0.2, 11.0, 0.6, 1.75),
    Obstacle("radiator_1", 2.5, 0.0, 3.7, 0.1, 0.8),
    Obstacle("radiator_2", 3.0, 3.1, 4.2, 3.2, 0.8),
)
CORRIDOR_SENSORS = (
    ("end_a", 0.2, 1.6, 2.2, 0.0, 12.0),
    ("end_b", 13.8, 1.6, 2.2, 180.0, 12.0),
)


def _corridor(seed: int, rng: np.random.Generator) -> tuple:
    room = Room(14.0, 3.2, obstacles=CORRIDOR_CLUTTER, doors=((0.0, 1.6), (14.0, 1.6)))
    sensors = [_sensor(*s) for s in CORRIDOR_SENSORS]
    spots = [(3.0, 1.6), (5.6, 1.2), (7.2, 2.0), (9.0, 1.4), (11.5, 1.8)]

    def director(r: np.random.Generator) -> Director:
        return VisitorDirector(room, spots, 3.0, 7, 3, 0.0, r)

    return room, sensors, director, 120.0


_BUILDERS: dict[str, tuple[Callable[..., tuple], str]] = {
    "crowd": (_crowd, "7 people moving randomly 1-9 m from a sensor; 3 Kinect v2"),
    "distance": (_distance, "2 people walking out to 10 m from one sensor and back"),
    "occlusions": (_occlusions, "2 people walking behind tall cabinets, 1-8 m from one sensor"),
    "classroom": (_classroom, "a teacher and 15-20 children playing the drum game in a circle"),
    "installation": (_installation, "visitors entering an art space, looking, leaving"),
    "stress": (_stress, "120 people in a 30 x 16 m hall, 10 sensors"),
    "reentry": (
        _reentry,
        "6 people who leave by a door, stay out 10-120 s and come back as themselves",
    ),
    "uniforms": (_uniforms, "the classroom with everyone in one of two school uniforms"),
    "overhead": (
        _overhead,
        "people crossing an entrance hall under 3 ceiling sensors looking straight down",
    ),
    "corridor": (
        _corridor,
        "people walking down a corridor past poster boards, a bookshelf and a coat rack",
    ),
    "walk": (_walk, "one person walking through the art space to calibrate its sensors"),
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


def _check_options(name: str, options: dict[str, int]) -> None:
    """Raise ConfigError unless ``options`` are the scenario's own, with valid values."""
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


def build_scenario(
    name: str,
    seed: int = 0,
    duration_s: float | None = -1.0,
    sensors: Sequence[SensorConfig] | None = None,
    profile: str | NoiseProfile = "ideal",
    embeddings: bool = False,
    calibration: Mapping[str, SensorCalibration] | None = None,
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
    profile : {"ideal", "realistic", "harsh"} or NoiseProfile
        The sensors' noise profile. Its per-sensor draws (calibration and clock offsets,
        jitter, drops, misses) and the room's decoys come from ``seed``. A name may end
        in ``+embeddings`` (:func:`~openptrack_py.sim.profiles.resolve_profile`).
    embeddings : bool
        Turn the profile's simulated identity embeddings on (off leaves it as it is).
    calibration : mapping of str to SensorCalibration, optional
        Calibration entries by sensor id: those sensors report through the calibrated
        pose and correct their stamps by the calibrated clock offset.
    **options
        Scenario parameters: ``people`` (crowd, stress, reentry), ``children``
        (classroom, uniforms).

    Raises
    ------
    ConfigError
        For an unknown scenario, option or profile.
    """
    noise = resolve_profile(profile)
    if embeddings and not noise.embeddings:
        noise = noise.with_embeddings()
    if name not in _BUILDERS:
        raise ConfigError(f"scenario: unknown {name!r} (allowed: {', '.join(SCENARIO_NAMES)})")
    builder, description = _BUILDERS[name]
    _check_options(name, options)
    root = np.random.SeedSequence(seed)
    layout_rng = np.random.default_rng(root.spawn(1)[0])
    room, default_sensors, make_director, default_duration = builder(seed, layout_rng, **options)
    chosen = list(sensors) if sensors else default_sensors
    phase_rng = np.random.default_rng([seed, 7])
    simulated = [cfg for cfg in chosen if cfg.source == "sim"]
    specs = []
    for cfg in simulated:
        rate = cfg.rate_hz or SENSOR_TYPES[cfg.type].rate_hz
        phase = float(phase_rng.uniform(0, 1.0 / rate))
        entry = None if calibration is None else calibration.get(cfg.id)
        specs.append(SensorSpec.from_config(cfg, phase_s=phase, calibration=entry))
    specs = list(draw_sensor_faults(noise, specs, simulated, seed))
    decoys: tuple[Decoy, ...] = ()
    if noise.decoys_per_sensor > 0 and specs:
        count = math.ceil(noise.decoys_per_sensor * len(specs))
        views = [SensorView(spec, room) for spec in specs]
        decoys = place_decoys(room, views, count, np.random.default_rng([seed, 61]))
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
        profile=noise,
        decoys=decoys,
    )


def scenario_world(scenario: Scenario, dt: float = 0.04) -> World:
    """The scenario's world, seeded as :class:`Simulator` seeds it.

    Every process that simulates part of a scenario builds its world with this, so they
    all agree on where everybody is.
    """
    world_seq, _ = np.random.SeedSequence(scenario.seed).spawn(2)
    rng = np.random.default_rng(world_seq)
    return World(scenario.room, scenario.make_director(rng), rng, dt=dt)
