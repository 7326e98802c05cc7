"""Tests for openptrack_py.sim: world, sensor models, scenarios, event stream, live player.

Every run is seeded, so every statistical assertion below is deterministic; the margins
are still several standard errors wide so that a change of seed would not break them,
yet narrow enough to fail if the model behind them were wrong (e.g. Kinect v1 and v2
noise swapped, miss probability ignored, pose error not applied).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections import defaultdict
from collections.abc import Iterable, Sequence

import numpy as np
import pytest

from openptrack_py.config import NetworkConfig, Pose, PoseError, SensorConfig, SimConfig
from openptrack_py.errors import ConfigError
from openptrack_py.messages import (
    DetectionBatch,
    decode_detection_batch,
    decode_ground_truth,
    encode_detection_batch,
    encode_ground_truth,
)
from openptrack_py.runtime.node import Node
from openptrack_py.sensor_types import SENSOR_TYPES
from openptrack_py.sim import (
    DEFAULT_START_TIME,
    SCENARIO_NAMES,
    SENSOR_NOISE,
    Obstacle,
    PersonSpec,
    Room,
    Scenario,
    SensorFrame,
    SensorModel,
    SensorSpec,
    Simulator,
    TruthFrame,
    World,
    build_scenario,
)
from openptrack_py.sim.directors import ShuttleDirector
from openptrack_py.sim.live import LivePlayer, scenario_from_network
from openptrack_py.sim.sensor_spec import APPEARANCE_BINS, APPEARANCE_LENGTH
from openptrack_py.sim.world import Snapshot
from openptrack_py.transport import MemoryBus
from tests.conftest import people_snapshot

# --------------------------------------------------------------------------- helpers


def _pose(x: float, y: float, z: float, yaw: float, pitch: float) -> Pose:
    return Pose(x=x, y=y, z=z, yaw_deg=yaw, pitch_deg=pitch)


_snap = people_snapshot


def _model(
    kind: str = "kinect2",
    pose: Pose | None = None,
    room: Room | None = None,
    seed: int = 0,
    **spec_options: object,
) -> SensorModel:
    spec = SensorSpec(
        id="s",
        type=SENSOR_TYPES[kind],
        pose=pose if pose is not None else _pose(0.0, 5.0, 2.2, 0.0, 12.0),
        rate_hz=30.0,
        **spec_options,  # type: ignore[arg-type]
    )
    return SensorModel(spec, room if room is not None else Room(20.0, 10.0), _rng(seed))


def _rng(seed: int) -> np.random.Generator:
    return np.random.default_rng(seed)


def _detection_rate(model: SensorModel, snap: Snapshot, person: int, frames: int) -> float:
    return float(np.mean([person in model.observe(snap).person_ids for _ in range(frames)]))


def _events(scenario: Scenario, **kwargs: object) -> list[SensorFrame | TruthFrame]:
    return list(Simulator(scenario, **kwargs).events())  # type: ignore[arg-type]


def _fingerprint(events: Iterable[SensorFrame | TruthFrame]) -> list[tuple]:
    out: list[tuple] = []
    for ev in events:
        if isinstance(ev, SensorFrame):
            out.append(
                ("S", ev.time, ev.capture_time, encode_detection_batch(ev.batch), ev.person_ids)
            )
        else:
            out.append(("T", ev.time, encode_ground_truth(ev.frame)))
    return out


def _truth_paths(events: Iterable[SensorFrame | TruthFrame]) -> list[tuple]:
    """Everyone's state per truth frame, without the sensor-dependent ``covered`` flag."""
    return [
        (
            ev.frame.seq,
            ev.frame.stamp,
            *((p.id, p.x, p.y, p.vx, p.vy, p.height, p.kind) for p in ev.frame.people),
        )
        for ev in events
        if isinstance(ev, TruthFrame)
    ]


def _without_sensors(scenario: Scenario) -> Scenario:
    """The same people and paths, no sensors (fast ground-truth-only runs)."""
    return dataclasses.replace(scenario, sensors=())


def _tracks(events: Iterable[SensorFrame | TruthFrame]) -> dict[int, np.ndarray]:
    """Per person id: rows ``(t, x, y, vx, vy, height)`` from the truth frames."""
    rows: dict[int, list[tuple[float, ...]]] = defaultdict(list)
    for ev in events:
        if isinstance(ev, TruthFrame):
            t = ev.frame.stamp - DEFAULT_START_TIME
            for p in ev.frame.people:
                rows[p.id].append((t, p.x, p.y, p.vx, p.vy, p.height))
    return {k: np.array(v) for k, v in rows.items()}


def _still_scenario(
    room: Room, sensors: Sequence[SensorSpec], spots: Sequence[tuple[float, float]], seed: int
) -> Scenario:
    """People standing still at ``spots`` for the whole run."""

    def director(r: np.random.Generator) -> ShuttleDirector:
        return ShuttleDirector(
            routes=[[s] for s in spots], pause_s=1.0, start_delay_s=[1e9] * len(spots), rng=r
        )

    return Scenario(
        name="still", seed=seed, duration_s=2.0, room=room, sensors=tuple(sensors),
        make_director=director,
    )  # fmt: skip


def _segment_crosses_box(a: np.ndarray, b: np.ndarray, o: Obstacle) -> bool:
    s = np.linspace(0.0, 1.0, 100)[:, None]
    q = a + (b - a) * s
    return bool(np.any((q[:, 0] > o.x0) & (q[:, 0] < o.x1) & (q[:, 1] > o.y0) & (q[:, 1] < o.y1)))


# ============================================================== 1. determinism


SHORT = {"crowd": 3.0, "distance": 3.0, "occlusions": 3.0, "classroom": 3.0,
         "installation": 3.0, "stress": 0.5, "reentry": 3.0, "uniforms": 3.0, "overhead": 3.0,
         "corridor": 3.0, "walk": 3.0}  # fmt: skip


@pytest.mark.parametrize("name", SCENARIO_NAMES, ids=list(SCENARIO_NAMES))
def test_same_name_and_seed_give_identical_streams(name: str) -> None:
    a = _fingerprint(Simulator(build_scenario(name, seed=4, duration_s=SHORT[name])).events())
    b = _fingerprint(Simulator(build_scenario(name, seed=4, duration_s=SHORT[name])).events())
    assert len(a) > 10
    assert any(e[0] == "S" for e in a) and any(e[0] == "T" for e in a)
    assert a == b


@pytest.mark.parametrize("name", ["crowd", "classroom", "installation"], ids=str)
def test_different_seeds_give_different_streams(name: str) -> None:
    a = _events(build_scenario(name, seed=1, duration_s=2.0))
    b = _events(build_scenario(name, seed=2, duration_s=2.0))
    assert _truth_paths(a) != _truth_paths(b)
    first_a = next(e for e in a if isinstance(e, TruthFrame)).frame.people
    first_b = next(e for e in b if isinstance(e, TruthFrame)).frame.people
    assert [(p.x, p.y) for p in first_a] != [(p.x, p.y) for p in first_b]
    dets_a = [encode_detection_batch(e.batch) for e in a if isinstance(e, SensorFrame)]
    dets_b = [encode_detection_batch(e.batch) for e in b if isinstance(e, SensorFrame)]
    assert dets_a != dets_b


def test_sensors_do_not_change_the_peoples_paths() -> None:
    base = build_scenario("crowd", seed=5, duration_s=6.0)
    cfgs = [SensorConfig(id=s.id, type=s.type.name, pose=s.pose) for s in base.sensors]  # type: ignore[arg-type]
    extra = SensorConfig(id="extra", type="kinect1", pose=_pose(5.0, 5.0, 3.0, 10.0, 60.0))
    other = SensorConfig(id="other", type="sr4500", rate_hz=7.0, pose=_pose(9.0, 9.0, 2.0, 200, 5))
    reference = _truth_paths(_events(base))
    assert len(reference) == 6 * 30 + 1
    for sensors in ([*cfgs, extra], [other], [extra, *cfgs]):
        scenario = build_scenario("crowd", seed=5, duration_s=6.0, sensors=sensors)
        assert [s.id for s in scenario.sensors] == [c.id for c in sensors]
        assert _truth_paths(_events(scenario)) == reference
    assert _truth_paths(_events(_without_sensors(base))) == reference


# ============================================================ 2. event stream

STREAM_SENSORS = [
    SensorConfig(
        id="fast", type="kinect2", pose=_pose(0.2, 0.2, 2.6, 45.0, 22.0),
        clock_offset_s=0.75, latency_s=0.05, latency_jitter_s=0.004,
    ),
    SensorConfig(
        id="slow", type="sr4500", pose=_pose(9.8, 0.2, 2.6, 135.0, 22.0),
        clock_offset_s=-2.5, latency_s=0.2, latency_jitter_s=0.01, frame_drop_probability=0.25,
    ),
    SensorConfig(
        id="custom", type="kinect1", rate_hz=15.0, pose=_pose(5.0, 9.8, 2.6, -90.0, 22.0),
        clock_offset_s=0.0, latency_s=0.1, latency_jitter_s=0.008,
    ),
]  # fmt: skip
STREAM_DURATION = 20.0


@pytest.fixture(scope="module")
def stream() -> tuple[Scenario, list[SensorFrame | TruthFrame]]:
    scenario = build_scenario("crowd", seed=11, duration_s=STREAM_DURATION, sensors=STREAM_SENSORS)
    return scenario, _events(scenario)


def _frames_by_sensor(events: Iterable[SensorFrame | TruthFrame]) -> dict[str, list[SensorFrame]]:
    out: dict[str, list[SensorFrame]] = defaultdict(list)
    for ev in events:
        if isinstance(ev, SensorFrame):
            out[ev.batch.sensor_id].append(ev)
    return out


def test_events_are_time_ordered(stream) -> None:
    _, events = stream
    times = np.array([ev.time for ev in events])
    assert len(times) > 1000
    assert np.all(np.diff(times) >= 0.0)
    for ev in events:
        if isinstance(ev, SensorFrame):
            assert ev.time >= ev.capture_time
            assert ev.capture_time <= DEFAULT_START_TIME + STREAM_DURATION + 1e-9
        else:
            assert ev.time == ev.frame.stamp
    assert {type(ev) for ev in events} == {SensorFrame, TruthFrame}


def test_specs_follow_the_sensor_configs(stream) -> None:
    scenario, _ = stream
    specs = {s.id: s for s in scenario.sensors}
    assert list(specs) == ["fast", "slow", "custom"]
    assert specs["fast"].rate_hz == 30.0 and specs["slow"].rate_hz == 13.0
    assert specs["custom"].rate_hz == 15.0
    assert specs["slow"].type.name == "sr4500"
    # type defaults filled in when the config leaves them out
    assert specs["custom"].miss_probability == SENSOR_NOISE["kinect1"].miss_probability
    assert specs["custom"].clutter_per_frame == SENSOR_NOISE["kinect1"].clutter_per_frame
    for s in specs.values():
        assert 0.0 <= s.phase_s < 1.0 / s.rate_hz


@pytest.mark.parametrize("sensor_id", ["fast", "custom"], ids=str)
def test_seq_counts_every_frame_without_drops(stream, sensor_id: str) -> None:
    scenario, events = stream
    spec = next(s for s in scenario.sensors if s.id == sensor_id)
    frames = _frames_by_sensor(events)[sensor_id]
    expected = math.floor((STREAM_DURATION - spec.phase_s) * spec.rate_hz + 1e-9) + 1
    assert [f.batch.seq for f in frames] == list(range(expected))


def test_dropped_frames_leave_seq_gaps(stream) -> None:
    scenario, events = stream
    spec = next(s for s in scenario.sensors if s.id == "slow")
    frames = _frames_by_sensor(events)["slow"]
    seqs = np.array([f.batch.seq for f in frames])
    total = math.floor((STREAM_DURATION - spec.phase_s) * spec.rate_hz + 1e-9) + 1
    assert np.all(np.diff(seqs) >= 1), "seq must increase in publication order"
    assert seqs.max() < total
    assert np.any(np.diff(seqs) > 1), "dropped frames must leave gaps"
    kept = len(seqs) / total
    assert 0.75 - 0.08 < kept < 0.75 + 0.08
    assert len(set(seqs.tolist())) == len(seqs)


@pytest.mark.parametrize("sensor_id", ["fast", "slow", "custom"], ids=str)
def test_capture_times_follow_rate_and_phase(stream, sensor_id: str) -> None:
    scenario, events = stream
    spec = next(s for s in scenario.sensors if s.id == sensor_id)
    for f in _frames_by_sensor(events)[sensor_id]:
        expected = DEFAULT_START_TIME + spec.phase_s + f.batch.seq / spec.rate_hz
        assert f.capture_time == pytest.approx(expected, abs=1e-6)


@pytest.mark.parametrize(
    ("sensor_id", "offset"), [("fast", 0.75), ("slow", -2.5), ("custom", 0.0)], ids=str
)
def test_stamp_is_capture_time_plus_clock_offset(stream, sensor_id: str, offset: float) -> None:
    _, events = stream
    frames = _frames_by_sensor(events)[sensor_id]
    assert frames
    for f in frames:
        assert f.batch.stamp == f.capture_time + offset
        assert f.batch.sensor_id == sensor_id
        assert f.batch.frame_id == "world"
        assert len(f.person_ids) == len(f.batch.detections)


@pytest.mark.parametrize(
    ("sensor_id", "latency", "jitter"),
    [("fast", 0.05, 0.004), ("slow", 0.2, 0.01), ("custom", 0.1, 0.008)],
    ids=["fast", "slow", "custom"],
)
def test_arrival_delay_matches_latency_and_jitter(
    stream, sensor_id: str, latency: float, jitter: float
) -> None:
    _, events = stream
    delay = np.array([f.time - f.capture_time for f in _frames_by_sensor(events)[sensor_id]])
    assert len(delay) > 150
    assert delay.mean() == pytest.approx(latency, abs=3.5 * jitter / math.sqrt(len(delay)) + 1e-4)
    assert delay.std() == pytest.approx(jitter, rel=0.25)


def test_ground_truth_frames_at_their_rate(stream) -> None:
    _, events = stream
    truth = [ev for ev in events if isinstance(ev, TruthFrame)]
    assert [t.frame.seq for t in truth] == list(range(int(STREAM_DURATION * 30) + 1))
    for t in truth:
        assert t.frame.stamp == pytest.approx(DEFAULT_START_TIME + t.frame.seq / 30.0, abs=1e-9)
        assert len(t.frame.people) == 7


def test_start_time_and_truth_rate_options() -> None:
    scenario = build_scenario("distance", seed=0, duration_s=2.0)
    events = _events(scenario, start_time=1000.0, ground_truth_rate_hz=4.0)
    truth = [e for e in events if isinstance(e, TruthFrame)]
    assert [t.time for t in truth] == pytest.approx([1000.0 + k / 4 for k in range(9)])
    frames = [e for e in events if isinstance(e, SensorFrame)]
    assert 1000.0 <= frames[0].capture_time < 1000.0 + 1 / 30
    assert not any(isinstance(e, TruthFrame) for e in _events(scenario, ground_truth_rate_hz=None))


def test_large_jitter_never_reorders_one_sensors_frames() -> None:
    cfg = SensorConfig(
        id="k", type="kinect2", pose=_pose(0.2, 0.2, 2.6, 45.0, 22.0),
        latency_s=0.1, latency_jitter_s=0.03,
    )  # fmt: skip
    events = _events(build_scenario("crowd", seed=3, duration_s=5.0, sensors=[cfg]))
    seqs = [e.batch.seq for e in events if isinstance(e, SensorFrame)]
    assert seqs == sorted(seqs)


# ====================================================== 3. scenario contents


def test_crowd_has_seven_adults_and_three_sensors() -> None:
    scenario = build_scenario("crowd", seed=2, duration_s=20.0)
    assert len(scenario.sensors) == 3
    assert len({s.id for s in scenario.sensors}) == 3
    assert scenario.room.width == 10.0 and scenario.room.depth == 10.0
    first = scenario.sensors[0].pose
    events = _events(_without_sensors(scenario), ground_truth_rate_hz=5.0)
    tracks = _tracks(events)
    assert len(tracks) == 7
    for ev in events:
        assert isinstance(ev, TruthFrame)
        assert len(ev.frame.people) == 7
        for p in ev.frame.people:
            assert p.kind == "adult"
            assert 1.55 <= p.height <= 1.95
            assert 0.8 <= math.hypot(p.x - first.x, p.y - first.y) <= 9.3
    # they move around: everyone covers some ground
    for rows in tracks.values():
        assert np.ptp(rows[:, 1]) + np.ptp(rows[:, 2]) > 1.0


def test_crowd_people_option() -> None:
    scenario = build_scenario("crowd", seed=2, duration_s=0.5, people=12)
    truth = [e for e in _events(scenario) if isinstance(e, TruthFrame)]
    assert all(len(t.frame.people) == 12 for t in truth)


def test_distance_people_walk_out_to_ten_metres() -> None:
    scenario = build_scenario("distance", seed=1, duration_s=20.0)
    assert len(scenario.sensors) == 1
    sensor = scenario.sensors[0].pose
    events = _events(scenario, ground_truth_rate_hz=10.0)
    tracks = _tracks(events)
    assert len(tracks) == 2
    for rows in tracks.values():
        dist = np.hypot(rows[:, 1] - sensor.x, rows[:, 2] - sensor.y)
        assert dist[0] < 1.5
        assert 9.8 <= dist.max() <= 10.8
    far = [
        d.distance
        for e in events
        if isinstance(e, SensorFrame)
        for d, pid in zip(e.batch.detections, e.person_ids, strict=True)
        if pid
    ]
    assert max(far) > 9.0  # the sensor still sees them far out


def test_occlusions_people_hide_behind_cabinets() -> None:
    scenario = build_scenario("occlusions", seed=0, duration_s=30.0)
    cabinets = [o for o in scenario.room.obstacles if o.height > 1.9]
    assert len(cabinets) == 2 and len(scenario.sensors) == 1
    assert any(o.height == 0.75 for o in scenario.room.obstacles)
    sensor = scenario.sensors[0].pose
    origin = np.array([sensor.x, sensor.y])
    events = _events(scenario, ground_truth_rate_hz=30.0)
    truth = [e for e in events if isinstance(e, TruthFrame)]
    truth_times = np.array([t.time for t in truth])
    hidden_behind = defaultdict(int)
    behind = detected_behind = clear = detected_clear = 0
    for frame in (e for e in events if isinstance(e, SensorFrame)):
        gt = truth[int(np.argmin(np.abs(truth_times - frame.capture_time)))].frame
        assert len(gt.people) == 2
        a, b = gt.people
        for p in gt.people:
            xy = np.array([p.x, p.y])
            seen = p.id in frame.person_ids
            if any(_segment_crosses_box(origin, xy, o) for o in cabinets):
                assert p.covered  # inside the field of view, just hidden
                behind += 1
                detected_behind += seen
                hidden_behind[p.id] += not seen
            elif p.covered and math.hypot(a.x - b.x, a.y - b.y) > 1.5:
                clear += 1
                detected_clear += seen
    assert set(hidden_behind) == {1, 2}
    assert min(hidden_behind.values()) > 60  # each person hidden for more than 2 s
    assert detected_behind / behind < 0.03
    assert clear > 200 and detected_clear / clear > 0.8


@pytest.fixture(scope="module")
def classroom() -> tuple[Scenario, dict[int, np.ndarray], dict[int, str]]:
    scenario = build_scenario("classroom", seed=3, duration_s=23.0)
    events = _events(_without_sensors(scenario), ground_truth_rate_hz=10.0)
    kinds = {p.id: p.kind for e in events for p in e.frame.people}  # type: ignore[union-attr]
    return scenario, _tracks(events), kinds


def test_classroom_has_a_teacher_and_children(classroom) -> None:
    scenario, tracks, kinds = classroom
    assert len(scenario.sensors) == 3
    children = [i for i, k in kinds.items() if k == "child"]
    adults = [i for i, k in kinds.items() if k == "adult"]
    assert len(adults) == 1
    assert 15 <= len(children) <= 20
    for i in children:
        assert np.all((tracks[i][:, 5] >= 0.8) & (tracks[i][:, 5] <= 1.2))
    assert tracks[adults[0]][0, 5] >= 1.55


def _angle_about_centre(rows: np.ndarray, centre: tuple[float, float] = (4.0, 3.6)) -> np.ndarray:
    return np.unwrap(np.arctan2(rows[:, 2] - centre[1], rows[:, 1] - centre[0]))


def test_classroom_children_walk_clockwise_then_stop(classroom) -> None:
    _, tracks, kinds = classroom
    children = [i for i, k in kinds.items() if k == "child"]
    for i in children:
        rows = tracks[i]
        t = rows[:, 0]
        angle = _angle_about_centre(rows)
        radius = np.hypot(rows[:, 1] - 4.0, rows[:, 2] - 3.6)
        assert np.all((radius > 1.6) & (radius < 2.8))  # on the circle
        walk = (t >= 3.0) & (t <= 15.0)
        # clockwise: the angle decreases steadily (0.22 rad/s group speed)
        assert angle[walk][-1] - angle[walk][0] < -2.0
        assert np.all(np.diff(angle[walk]) < 0.0)
        speed = np.hypot(rows[:, 3], rows[:, 4])
        assert speed[walk].mean() > 0.3
        stop = (t >= 20.0) & (t <= 21.5)
        assert speed[stop].max() < 0.25
        assert abs(angle[stop][-1] - angle[stop][0]) < 0.12  # walking: ~0.33 rad in 1.5 s


def test_classroom_children_option() -> None:
    scenario = build_scenario("classroom", seed=0, duration_s=0.2, children=9)
    truth = [e for e in _events(_without_sensors(scenario)) if isinstance(e, TruthFrame)]
    kinds = [p.kind for p in truth[0].frame.people]
    assert kinds.count("child") == 9 and kinds.count("adult") == 1


def test_installation_visitors_enter_and_leave_by_the_doors() -> None:
    scenario = build_scenario("installation", seed=0, duration_s=60.0)
    doors = np.array(
        [
            [
                np.clip(x, 0.3, scenario.room.width - 0.3),
                np.clip(y, 0.3, scenario.room.depth - 0.3),
            ]
            for x, y in scenario.room.doors
        ]
    )
    assert len(doors) >= 2
    events = _events(_without_sensors(scenario), ground_truth_rate_hz=10.0)
    counts = []
    gone: set[int] = set()
    present_before: set[int] = set()
    max_seen = 0
    for ev in events:
        assert isinstance(ev, TruthFrame)
        ids = [p.id for p in ev.frame.people]
        assert len(ids) == len(set(ids))
        now = set(ids)
        counts.append(len(now))
        assert not now & gone, "an id came back after leaving"
        for p in ev.frame.people:
            if p.id not in present_before and ev.frame.seq > 0:
                assert p.id > max_seen, "ids must be fresh"
                # newcomers appear at a door
                assert np.min(np.hypot(*(doors - [p.x, p.y]).T)) < 0.5
        gone |= present_before - now
        present_before = now
        max_seen = max(max_seen, *now) if now else max_seen
    tracks = _tracks(events)
    assert len(tracks) > counts[0] + 3  # new people arrived
    assert len(gone) >= 2  # and some left
    assert len(set(counts)) >= 3
    for pid in gone:
        last = tracks[pid][-1]
        assert np.min(np.hypot(*(doors - last[1:3]).T)) < 0.8  # they leave by a door


def _presence(scenario: Scenario, rate_hz: float = 5.0) -> dict[int, np.ndarray]:
    """Per ground-truth id, the times (s) of the truth frames that hold the person."""
    sim = Simulator(_without_sensors(scenario), ground_truth_rate_hz=rate_hz)
    seen: dict[int, list[float]] = defaultdict(list)
    for ev in sim.events(sensor_frames=False):
        for p in ev.frame.people:
            seen[p.id].append(ev.frame.stamp - DEFAULT_START_TIME)
    return {k: np.array(v) for k, v in seen.items()}


def test_reentry_people_come_back_as_themselves_after_10_to_120_s() -> None:
    scenario = build_scenario("reentry", seed=1)
    assert scenario.duration_s == 300.0 and len(scenario.sensors) == 3
    assert len(scenario.room.doors) == 3
    seen = _presence(scenario)
    assert sorted(seen) == [1, 2, 3, 4, 5, 6]  # nobody new: the same six come back
    for pid, times in seen.items():
        gaps = np.diff(times)
        away = gaps[gaps > 0.5]
        assert len(away) >= 2, f"person {pid} came back {len(away)} times"
        assert np.all((away >= 10.0) & (away <= 121.0)), away
    # they come back in the clothes they left in
    sim = Simulator(_without_sensors(scenario))
    looks: dict[int, set[tuple[float, ...]]] = defaultdict(set)
    for t in np.arange(0.0, 300.0, 1.0):
        snap = sim.world.state_at(float(t))
        top, bottom = snap.clothing()
        for i, pid in enumerate(snap.ids.tolist()):
            looks[pid].add((*top[i], *bottom[i], snap.height[i]))
    assert all(len(v) == 1 for v in looks.values())
    # a door is where they leave and where they come back
    truth = _tracks(_events(_without_sensors(scenario)))
    doors = np.array([(0.3, 3.0), (7.7, 1.2), (4.0, 0.3)])
    for pid, rows in truth.items():
        breaks = np.flatnonzero(np.diff(rows[:, 0]) > 0.5)
        for b in breaks:
            for xy in (rows[b, 1:3], rows[b + 1, 1:3]):
                assert np.min(np.linalg.norm(doors - xy, axis=1)) < 0.6, (pid, xy)


def test_reentry_people_option() -> None:
    assert len(_presence(build_scenario("reentry", seed=0, duration_s=2.0, people=3))) == 3


def test_a_returning_person_keeps_their_id() -> None:
    world = World(Room(6.0, 6.0), _Push([(1.0, 1.0), (3.0, 3.0)], (0.0, 0.0)), _rng(0))
    spec = PersonSpec("adult", 1.8, 0.2, 10.0, 200.0, 1.0, 0.1, 0.9, 0.5, 0.3)
    slot = int(np.flatnonzero(world.ids == 1)[0])
    world.remove_person(slot)
    with pytest.raises(ValueError, match="person 2 is already in the world"):
        world.add_person(spec, (5.0, 5.0), person_id=2)
    back = world.add_person(spec, (5.0, 5.0), person_id=1)
    assert world.ids[back] == 1
    snap = world.snapshot()
    top, bottom = snap.clothing()
    row = int(np.flatnonzero(snap.ids == 1)[0])
    assert top[row].tolist() == [10.0, 0.1, 0.9] and bottom[row].tolist() == [200.0, 0.5, 0.3]
    fresh = world.add_person(spec, (2.0, 5.0))
    assert world.ids[fresh] == 3  # fresh ids never repeat one in use or used
    world.add_person(spec, (4.0, 1.0), person_id=9)
    assert world.ids[world.add_person(spec, (1.0, 4.0))] == 10
    with pytest.raises(ValueError, match=">= 1"):
        world.add_person(spec, (1.0, 2.0), person_id=0)


def test_standing_people_keep_facing_where_they_walked() -> None:
    world = World(Room(10.0, 10.0), _Push([(2.0, 5.0)], (1.0, 0.0)), _rng(0))
    world.advance_to(2.0)
    assert world.snapshot().facing()[0] == pytest.approx([1.0, 0.0], abs=1e-6)
    world.director = _Push([], (0.0, 0.0))  # stop
    world.advance_to(5.0)
    snap = world.snapshot()
    assert np.linalg.norm(snap.vel[0]) < 0.01
    assert snap.facing()[0] == pytest.approx([1.0, 0.0], abs=1e-6)


def test_stress_has_many_people_and_ten_sensors() -> None:
    scenario = build_scenario("stress", seed=0, duration_s=0.5)
    assert len(scenario.sensors) == 10
    assert len({s.id for s in scenario.sensors}) == 10
    events = _events(scenario)
    truth = [e for e in events if isinstance(e, TruthFrame)]
    assert all(len(t.frame.people) >= 100 for t in truth)
    assert {e.batch.sensor_id for e in events if isinstance(e, SensorFrame)} == {
        s.id for s in scenario.sensors
    }


@pytest.mark.parametrize("name", SCENARIO_NAMES, ids=list(SCENARIO_NAMES))
def test_default_durations_and_open_ended_runs(name: str) -> None:
    assert build_scenario(name).duration_s is not None
    assert build_scenario(name).duration_s >= 60.0
    assert build_scenario(name, duration_s=None).duration_s is None
    assert build_scenario(name, duration_s=7.0).duration_s == 7.0


def test_open_ended_run_keeps_going() -> None:
    events = Simulator(build_scenario("distance", duration_s=None)).events()
    last = None
    for _, ev in zip(range(2000), events, strict=False):
        last = ev
    assert last is not None and last.time - DEFAULT_START_TIME > 20.0


def test_unknown_scenario_is_rejected_naming_the_allowed_ones() -> None:
    with pytest.raises(ConfigError) as info:
        build_scenario("party")
    message = str(info.value)
    assert "party" in message
    for name in SCENARIO_NAMES:
        assert name in message


@pytest.mark.parametrize(
    ("name", "options"),
    [("crowd", {"childs": 3}), ("distance", {"people": 3}), ("classroom", {"people": 4})],
    ids=["typo", "distance-people", "classroom-people"],
)
def test_unknown_option_is_rejected(name: str, options: dict[str, int]) -> None:
    with pytest.raises(ConfigError) as info:
        build_scenario(name, **options)
    assert next(iter(options)) in str(info.value)
    assert name in str(info.value)


def test_unknown_option_error_names_the_allowed_options() -> None:
    with pytest.raises(ConfigError) as info:
        build_scenario("crowd", childs=3)
    assert "people" in str(info.value)


def test_sensor_spec_needs_a_pose() -> None:
    with pytest.raises(ConfigError, match="pose"):
        SensorSpec.from_config(SensorConfig(id="x"))
    cfg = SensorConfig(id="x", type="sr4500", pose=_pose(0, 0, 2, 0, 10), miss_probability=0.5)
    spec = SensorSpec.from_config(cfg, phase_s=0.01)
    assert spec.rate_hz == SENSOR_TYPES["sr4500"].rate_hz
    assert spec.miss_probability == 0.5
    assert spec.clutter_per_frame == SENSOR_NOISE["sr4500"].clutter_per_frame
    assert spec.phase_s == 0.01


def test_non_sim_sensors_are_not_simulated() -> None:
    cfgs = [
        SensorConfig(id="real", source="camera", pose=_pose(0, 0, 2, 0, 10)),
        SensorConfig(id="virtual", pose=_pose(0.2, 2.0, 2, 0, 10)),
    ]
    scenario = build_scenario("distance", duration_s=1.0, sensors=cfgs)
    assert [s.id for s in scenario.sensors] == ["virtual"]


# =================================================== 4. sensor model physics

FRONT = _pose(0.0, 5.0, 2.2, 0.0, 12.0)


@pytest.mark.parametrize(
    ("kind", "xy"),
    [
        ("kinect2", (0.0, 5.0)),  # 2 m behind
        ("kinect2", (2.0, 9.0)),  # beside: outside the horizontal field of view
        ("kinect2", (12.6, 5.0)),  # 10.6 m ahead, beyond the 10 m range
        ("kinect1", (10.6, 5.0)),  # 8.6 m ahead, beyond the 8 m range
        ("kinect2", (2.3, 5.0)),  # nearly under the sensor: below the vertical view
    ],
    ids=["behind", "beside", "beyond-k2", "beyond-k1", "underneath"],
)
def test_person_outside_view_is_never_detected(kind: str, xy: tuple[float, float]) -> None:
    model = _model(kind, _pose(2.0, 5.0, 2.2, 0.0, 12.0), Room(20.0, 10.0), miss_probability=0.0)
    outside = _snap([(*xy, 1.75, 0.22, 0.0, 0.0)])
    assert not model.covers(outside.pos, outside.height)[0]
    assert _detection_rate(model, outside, 1, 200) == 0.0
    # control: the same person in front of the sensor is found
    inside = _snap([(6.0, 5.0, 1.75, 0.22, 0.0, 0.0)])
    assert model.covers(inside.pos, inside.height)[0]
    assert _detection_rate(model, inside, 1, 100) > 0.9


@pytest.mark.parametrize(
    ("height", "detected"),
    [(1.95, False), (0.75, True), (None, True)],
    ids=["cabinet", "table", "none"],
)
def test_furniture_hides_only_below_its_top(height: float | None, detected: bool) -> None:
    obstacles = () if height is None else (Obstacle("block", 3.0, 4.0, 3.6, 6.0, height),)
    model = _model(room=Room(20.0, 10.0, obstacles=obstacles), miss_probability=0.0)
    snap = _snap([(4.2, 5.0, 1.7, 0.22, 0.0, 0.0)])
    head, fraction = model.visibility(snap)
    rate = _detection_rate(model, snap, 1, 200)
    if detected:
        assert head[0] and fraction[0] > 0.6
        assert rate > 0.9
    else:
        assert not head[0] and fraction[0] == 0.0
        assert rate == 0.0
    # the ground truth still counts them as covered (occlusion ignored)
    assert model.covers(snap.pos, snap.height)[0]


def test_shorter_person_right_behind_another_is_hidden() -> None:
    model = _model(pose=_pose(0.0, 5.0, 2.0, 0.0, 10.0), miss_probability=0.0)
    behind = _snap([(3.0, 5.0, 1.9, 0.25, 0, 0), (3.6, 5.0, 1.6, 0.2, 180, 180)])
    head, fraction = model.visibility(behind)
    assert head.tolist() == [True, False]
    assert fraction[1] == 0.0
    assert _detection_rate(model, behind, 2, 200) == 0.0
    assert _detection_rate(model, behind, 1, 100) > 0.9
    # a metre to the side, the same person is in plain view
    aside = _snap([(3.0, 5.0, 1.9, 0.25, 0, 0), (3.6, 6.0, 1.6, 0.2, 180, 180)])
    assert model.visibility(aside)[0].tolist() == [True, True]
    assert _detection_rate(model, aside, 2, 100) > 0.9


def _along_ray_error_std(kind: str, distance: float, frames: int = 500) -> float:
    """Std of the error along the viewing ray for 5 people at ``distance`` m."""
    pose = _pose(0.0, 5.0, 1.2, 0.0, 5.0)
    model = _model(
        kind, pose, Room(20.0, 10.0), seed=int(distance * 10), miss_probability=0.0,
        clutter_per_frame=0.0,
    )  # fmt: skip
    bearings = np.radians([-22.0, -11.0, 0.0, 11.0, 22.0])
    xy = np.column_stack([distance * np.cos(bearings), 5.0 + distance * np.sin(bearings)])
    snap = _snap([(x, y, 1.7, 0.18, 0.0, 0.0) for x, y in xy])
    rays = np.column_stack([np.cos(bearings), np.sin(bearings)])
    errors = []
    for _ in range(frames):
        obs = model.observe(snap)
        for det, pid in zip(obs.detections, obs.person_ids, strict=True):
            if pid:
                errors.append((np.array([det.x, det.y]) - xy[pid - 1]) @ rays[pid - 1])
    assert len(errors) > 0.6 * 5 * frames
    return float(np.std(errors))


@pytest.fixture(scope="module")
def noise_by_distance() -> dict[str, list[float]]:
    return {
        k: [_along_ray_error_std(k, d) for d in (2.0, 4.0, 6.0)] for k in ("kinect1", "kinect2")
    }


def test_kinect1_noise_grows_quadratically_with_distance(noise_by_distance) -> None:
    s2, s4, s6 = noise_by_distance["kinect1"]
    model = SENSOR_NOISE["kinect1"]
    assert s2 == pytest.approx(float(model.depth_sigma_at(2.0)), rel=0.12)
    assert s6 == pytest.approx(float(model.depth_sigma_at(6.0)), rel=0.12)
    assert s6 / s2 > 3.0
    # quadratic: (s6 - s2) / (s4 - s2) = (36 - 4) / (16 - 4) = 2.67; linear would give 2
    assert 2.3 < (s6 - s2) / (s4 - s2) < 3.1


def test_kinect2_noise_is_nearly_constant(noise_by_distance) -> None:
    s2, _, s6 = noise_by_distance["kinect2"]
    assert s6 / s2 < 1.5
    assert s2 < 0.05 and s6 < 0.06
    k1 = noise_by_distance["kinect1"]
    assert (k1[2] / k1[0]) > 2.0 * (s6 / s2)


@pytest.mark.parametrize("miss", [0.1, 0.35], ids=["miss-0.1", "miss-0.35"])
def test_miss_probability_for_visible_close_people(miss: float) -> None:
    model = _model(miss_probability=miss, clutter_per_frame=0.0, seed=int(miss * 100))
    snap = _snap([(3.0, 5.0 + dy, 1.7, 0.2, 0.0, 0.0) for dy in (-1.2, 0.0, 1.2)])
    frames = 1200
    found = np.zeros(3)
    for _ in range(frames):
        ids = model.observe(snap).person_ids
        found += [i in ids for i in (1, 2, 3)]
    rate = 1.0 - found.sum() / (3 * frames)
    assert rate == pytest.approx(miss, abs=0.03)


def test_misses_grow_beyond_the_reliable_range() -> None:
    model = _model(pose=_pose(0.0, 5.0, 1.5, 0.0, 5.0), miss_probability=0.0)
    near = _snap([(4.0, 5.0, 1.7, 0.2, 0, 0)])
    far = _snap([(9.3, 5.0, 1.7, 0.2, 0, 0)])  # kinect2: reliable to 8 m, nothing past 10 m
    assert model.visibility(far)[1][0] == 1.0
    assert _detection_rate(model, near, 1, 300) > 0.98
    assert 0.4 < _detection_rate(model, far, 1, 300) < 0.85


@pytest.mark.parametrize("clutter", [0.2, 1.0], ids=["clutter-0.2", "clutter-1.0"])
def test_clutter_rate_is_poisson_with_the_configured_mean(clutter: float) -> None:
    pose = _pose(0.3, 10.0, 2.5, 0.0, 20.0)
    model = _model(
        pose=pose, room=Room(20.0, 20.0), clutter_per_frame=clutter, seed=int(clutter * 10)
    )
    snap = _snap([(10.0, 19.0, 1.7, 0.2, 0, 0)])  # out of view: every detection is clutter
    counts = []
    for _ in range(3000):
        obs = model.observe(snap)
        assert all(pid == 0 for pid in obs.person_ids)
        counts.append(len(obs.detections))
        for det in obs.detections:
            assert det.confidence <= 0.6
            rel = np.array([det.x - pose.x, det.y - pose.y])
            assert 0.9 <= np.hypot(*rel) <= SENSOR_TYPES["kinect2"].reliable_range_m + 0.1
            assert abs(math.degrees(math.atan2(rel[1], rel[0]))) < 35.3
    counts = np.array(counts)
    assert counts.mean() == pytest.approx(clutter, rel=0.15)
    assert np.mean(counts == 0) == pytest.approx(math.exp(-clutter), abs=0.03)


@pytest.mark.parametrize(
    "error",
    [PoseError(dx=0.5), PoseError(dy=-0.3), PoseError(dyaw_deg=10.0),
     PoseError(dx=0.2, dy=0.4, dyaw_deg=-5.0)],
    ids=["dx", "dy", "dyaw", "all"],
)  # fmt: skip
def test_pose_error_moves_detections_as_the_believed_pose(error: PoseError) -> None:
    pose = _pose(1.0, 5.0, 2.2, 0.0, 12.0)
    people = _snap([(4.0, 5.0, 1.7, 0.2, 0, 0), (5.0, 6.5, 1.8, 0.2, 90, 90)])
    true = _model(pose=pose, seed=9, clutter_per_frame=0.5)
    wrong = _model(pose=pose, seed=9, clutter_per_frame=0.5, pose_error=error)
    yaw = math.radians(error.dyaw_deg)
    rot = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    centre = np.array([pose.x, pose.y])
    shift = np.array([error.dx, error.dy])
    n = 0
    x_shift = []
    for _ in range(50):
        a, b = true.observe(people), wrong.observe(people)
        assert a.person_ids == b.person_ids
        for da, db, pid in zip(a.detections, b.detections, b.person_ids, strict=True):
            if pid == 1:
                x_shift.append(db.x - 4.0)
            expected = rot @ (np.array([da.x, da.y]) - centre) + centre + shift
            assert [db.x, db.y] == pytest.approx(expected.tolist(), abs=1e-9)
            assert db.z == pytest.approx(da.z, abs=1e-9)
            assert db.distance == pytest.approx(da.distance)  # the true range is unchanged
            n += 1
    assert n > 80
    if error.dyaw_deg == 0.0:  # e.g. dx = 0.5 m: reported x is 0.5 m off the true x
        assert np.mean(x_shift) == pytest.approx(error.dx, abs=0.02)


@pytest.mark.parametrize(("gap", "count"), [(0.2, 1), (0.6, 2)], ids=["merged", "apart"])
def test_people_closer_than_merge_distance_become_one_detection(gap: float, count: int) -> None:
    model = _model(miss_probability=0.0, clutter_per_frame=0.0)
    assert model.merge_distance_m == 0.3
    snap = _snap([(4.0, 5.0 - gap / 2, 1.7, 0.1, 0, 0), (4.0, 5.0 + gap / 2, 1.8, 0.1, 0, 0)])
    for _ in range(100):
        obs = model.observe(snap)
        real = [d for d, pid in zip(obs.detections, obs.person_ids, strict=True) if pid]
        assert len(real) == count
        if count == 1:
            assert real[0].y == pytest.approx(5.0, abs=0.12)  # at the pair's mean


@pytest.mark.parametrize(("merge", "count"), [(0.1, 2), (1.0, 1)], ids=["merge-0.1", "merge-1.0"])
def test_merge_distance_parameter(merge: float, count: int) -> None:
    spec = SensorSpec(
        id="s", type=SENSOR_TYPES["kinect2"], pose=FRONT, rate_hz=30.0, miss_probability=0.0,
        clutter_per_frame=0.0,
    )  # fmt: skip
    model = SensorModel(spec, Room(20.0, 10.0), _rng(1), merge_distance_m=merge)
    snap = _snap([(4.0, 4.8, 1.7, 0.1, 0, 0), (4.0, 5.2, 1.8, 0.1, 0, 0)])
    for _ in range(30):
        obs = model.observe(snap)
        assert sum(1 for pid in obs.person_ids if pid) == count


def test_detection_fields_in_a_scenario() -> None:
    scenario = build_scenario("crowd", seed=6, duration_s=8.0)
    sizes = {s.id: (s.type.width, s.type.height) for s in scenario.sensors}
    events = _events(scenario)
    heights = {p.id: p.height for e in events if isinstance(e, TruthFrame) for p in e.frame.people}
    errors, real_conf, clutter_conf = [], [], []
    for e in events:
        if not isinstance(e, SensorFrame):
            continue
        width, height = sizes[e.batch.sensor_id]
        for det, pid in zip(e.batch.detections, e.person_ids, strict=True):
            assert 0.0 <= det.confidence <= 1.0
            assert det.bbox is not None and det.appearance is not None
            u, v, w, h = det.bbox
            assert u >= 0 and v >= 0 and w >= 0 and h >= 0
            assert u + w <= width - 1 and v + h <= height - 1
            assert len(det.appearance) == APPEARANCE_LENGTH
            assert all(0 <= b <= 255 for b in det.appearance)
            assert 247 <= sum(det.appearance) <= 263
            assert det.distance > 0.0
            if pid:
                errors.append(det.height - heights[pid])
                real_conf.append(det.confidence)
                assert w > 0 and h > 0
            else:
                clutter_conf.append(det.confidence)
    errors = np.abs(errors)
    assert len(errors) > 500
    assert np.median(errors) < 0.05
    assert np.quantile(errors, 0.99) < 0.2
    assert np.mean(real_conf) > 0.6
    if clutter_conf:
        assert np.mean(clutter_conf) < np.mean(real_conf)


def test_appearance_reflects_clothing_colour() -> None:
    model = _model(miss_probability=0.0, clutter_per_frame=0.0)
    snap = _snap([(4.0, 3.5, 1.7, 0.2, 5.0, 5.0), (4.0, 6.5, 1.7, 0.2, 185.0, 185.0)])
    hists = defaultdict(list)
    for _ in range(20):
        obs = model.observe(snap)
        for det, pid in zip(obs.detections, obs.person_ids, strict=True):
            if pid:
                hists[pid].append(np.array(det.appearance))
    red, cyan = np.mean(hists[1], axis=0), np.mean(hists[2], axis=0)
    assert int(np.argmax(red)) == 0  # 5 degrees: first 22.5-degree bin
    assert int(np.argmax(cyan)) == 8  # 185 degrees
    assert np.abs(red - cyan).sum() > 200
    # the same person looks alike from frame to frame
    assert np.abs(hists[1][0] - hists[1][1]).sum() < np.abs(red - cyan).sum() / 2


def _signatures(model: SensorModel, snap: Snapshot, frames: int) -> dict[int, np.ndarray]:
    """Mean signature per person over ``frames`` frames."""
    rows: dict[int, list[np.ndarray]] = defaultdict(list)
    for _ in range(frames):
        obs = model.observe(snap)
        for det, pid in zip(obs.detections, obs.person_ids, strict=True):
            if pid:
                rows[pid].append(np.array(det.appearance))
    return {pid: np.mean(v, axis=0) for pid, v in rows.items()}


def test_appearance_of_black_grey_and_white_clothes_fills_the_achromatic_bins() -> None:
    dark, grey, light = APPEARANCE_BINS, APPEARANCE_BINS + 1, APPEARANCE_BINS + 2
    snap = dataclasses.replace(
        _snap([(3.0, 3.5, 1.7, 0.2, 0.0, 0.0), (4.0, 6.5, 1.7, 0.2, 0.0, 220.0)]),
        top_saturation=np.array([0.05, 0.04]),
        top_value=np.array([0.1, 0.92]),  # black, white
        bottom_saturation=np.array([0.03, 0.5]),
        bottom_value=np.array([0.55, 0.45]),  # grey, denim
    )
    sig = _signatures(_model(miss_probability=0.0, clutter_per_frame=0.0), snap, 20)
    black_grey, white_denim = sig[1], sig[2]
    assert black_grey[dark] > 0.45 * 255 and black_grey[grey] > 0.25 * 255
    assert black_grey[:APPEARANCE_BINS].sum() < 0.15 * 255  # a little skin and hair
    assert white_denim[light] + white_denim[grey] > 0.4 * 255
    assert np.argmax(white_denim[:APPEARANCE_BINS]) in (9, 10)  # 215-225 degrees


def test_each_sensor_has_its_own_cast_which_moves_no_detection() -> None:
    spec = SensorSpec(
        id="s", type=SENSOR_TYPES["kinect2"], pose=FRONT, rate_hz=30.0, clutter_per_frame=1.0
    )
    snap = _snap([(3.0, 4.0, 1.7, 0.2, 100.0, 300.0), (5.0, 6.0, 1.7, 0.2, 40.0, 200.0)])
    models = [
        SensorModel(spec, Room(20.0, 10.0), _rng(3), appearance_rng=_rng(seed))
        for seed in (10, 11)
    ]
    assert models[0].signatures.cast != models[1].signatures.cast
    assert abs(models[0].signatures.cast.hue_shift_deg) <= 8.0
    changed = 0
    for _ in range(30):
        a, b = (m.observe(snap) for m in models)
        assert a.person_ids == b.person_ids
        for da, db in zip(a.detections, b.detections, strict=True):
            assert (da.x, da.y, da.z, da.height, da.confidence, da.bbox) == (
                db.x, db.y, db.z, db.height, db.confidence, db.bbox,
            )  # fmt: skip
            changed += da.appearance != db.appearance
            assert len(da.appearance) == APPEARANCE_LENGTH
    assert changed > 30
    # without an appearance generator of its own, the model derives one from its seed
    # without drawing from the main one: positions are the same again
    derived = SensorModel(spec, Room(20.0, 10.0), _rng(3))
    first = SensorModel(spec, Room(20.0, 10.0), _rng(3), appearance_rng=_rng(10)).observe(snap)
    again = derived.observe(snap)
    assert [(d.x, d.y) for d in first.detections] == [(d.x, d.y) for d in again.detections]


def test_a_person_half_hidden_by_a_nearer_one_takes_on_their_colours() -> None:
    model = _model(miss_probability=0.0, clutter_per_frame=0.0)
    alone = _snap([(6.0, 5.0, 1.8, 0.2, 0.0, 0.0)])  # red, seen straight on
    hidden = _snap([(6.0, 5.0, 1.8, 0.2, 0.0, 0.0), (3.0, 5.22, 1.7, 0.2, 240.0, 240.0)])
    blue = 10  # 240 degrees
    red_alone = _signatures(model, alone, 10)[1]
    red_hidden = _signatures(model, hidden, 40)
    assert red_alone[blue] < 10
    assert red_hidden[1][blue] > 40  # the blue person in front lends their colours
    assert red_hidden[2][0] < 0.5 * red_hidden[1][blue]  # the one behind lends less
    assert red_hidden[2][blue] > 150


def test_clutter_has_random_signatures() -> None:
    model = _model(clutter_per_frame=3.0)
    sigs = [np.array(d.appearance) for _ in range(10) for d in model.observe(_snap([])).detections]
    assert len(sigs) > 10 and all(len(s) == APPEARANCE_LENGTH for s in sigs)
    assert len({int(np.argmax(s)) for s in sigs}) > 5


def test_bbox_grows_as_people_come_closer() -> None:
    model = _model(miss_probability=0.0, clutter_per_frame=0.0)
    boxes = {}
    for d in (2.5, 6.0):
        obs = model.observe(_snap([(d, 5.0, 1.7, 0.2, 0, 0)]))
        boxes[d] = obs.detections[0].bbox
    assert boxes[2.5][2] > boxes[6.0][2] and boxes[2.5][3] > boxes[6.0][3]
    # a centred person gets a centred box
    u, _, w, _ = boxes[6.0]
    assert abs(u + w / 2 - (SENSOR_TYPES["kinect2"].width - 1) / 2) < 5


def test_clutter_in_an_empty_room() -> None:
    model = _model(clutter_per_frame=3.0)
    obs = model.observe(_snap([]))
    assert len(obs.detections) > 0 and set(obs.person_ids) == {0}
    events = _events(build_scenario("crowd", seed=0, duration_s=1.0, people=0))
    assert any(isinstance(e, SensorFrame) and e.batch.detections for e in events)


# ============================================================== 5. ground truth


def test_covered_means_inside_some_sensors_view() -> None:
    room = Room(12.0, 10.0)
    sensors = [
        SensorSpec(id="a", type=SENSOR_TYPES["kinect2"], pose=_pose(0.2, 2.0, 2.5, 0, 15),
                   rate_hz=30.0, miss_probability=0.0),
        SensorSpec(id="b", type=SENSOR_TYPES["kinect2"], pose=_pose(11.8, 8.0, 2.5, 180, 15),
                   rate_hz=30.0, miss_probability=0.0),
    ]  # fmt: skip
    spots = [(4.0, 2.0), (8.0, 8.0), (0.5, 9.5), (11.5, 0.5)]
    events = _events(_still_scenario(room, sensors, spots, seed=3))
    truth = [e for e in events if isinstance(e, TruthFrame)]
    assert len(truth) == 61
    for t in truth:
        assert [p.id for p in t.frame.people] == [1, 2, 3, 4]
        assert [p.covered for p in t.frame.people] == [True, True, False, False]
    seen = defaultdict(set)
    for e in events:
        if isinstance(e, SensorFrame):
            seen[e.batch.sensor_id].update(pid for pid in e.person_ids if pid)
    assert seen["a"] == {1}
    assert seen["b"] == {2}


def test_truth_carries_kind_height_and_velocity() -> None:
    scenario = build_scenario("classroom", seed=1, duration_s=6.0)
    events = _events(_without_sensors(scenario), ground_truth_rate_hz=10.0)
    tracks = _tracks(events)
    for rows in tracks.values():
        assert np.ptp(rows[:, 5]) == 0.0  # stature is constant
        # reported velocity agrees with the displacement between frames
        v_num = np.diff(rows[:, 1:3], axis=0) / np.diff(rows[:, 0])[:, None]
        v_avg = 0.5 * (rows[1:, 3:5] + rows[:-1, 3:5])
        assert np.median(np.abs(v_num - v_avg)) < 0.05
    assert all(isinstance(e, TruthFrame) and not any(p.covered for p in e.frame.people)
               for e in events)  # fmt: skip


# ===================================================================== 6. world


@pytest.mark.parametrize("name", ["crowd", "occlusions", "classroom", "installation"], ids=str)
def test_people_stay_in_the_room_and_out_of_furniture(name: str) -> None:
    scenario = build_scenario(name, seed=2, duration_s=20.0)
    sim = Simulator(_without_sensors(scenario))
    world, room = sim.world, scenario.room
    touched_furniture = False
    for _ in range(500):
        world.step()
        idx = world.slots
        pos, r = world.pos[idx], world.radius[idx]
        assert np.all(pos[:, 0] >= r - 1e-9) and np.all(pos[:, 0] <= room.width - r + 1e-9)
        assert np.all(pos[:, 1] >= r - 1e-9) and np.all(pos[:, 1] <= room.depth - r + 1e-9)
        for o in room.obstacles:
            inside = (
                (pos[:, 0] > o.x0 - r + 1e-6)
                & (pos[:, 0] < o.x1 + r - 1e-6)
                & (pos[:, 1] > o.y0 - r + 1e-6)
                & (pos[:, 1] < o.y1 + r - 1e-6)
            )
            assert not inside.any(), f"someone stands in {o.name} at t={world.t:.2f}"
            near = (
                (pos[:, 0] > o.x0 - r - 0.05)
                & (pos[:, 0] < o.x1 + r + 0.05)
                & (pos[:, 1] > o.y0 - r - 0.05)
                & (pos[:, 1] < o.y1 + r + 0.05)
            )
            touched_furniture |= bool(near.any())
    if name == "occlusions":
        assert touched_furniture  # the routes brush past the cabinets: the check bites


class _Push:
    """Drives every person at a constant velocity."""

    def __init__(self, start: Sequence[tuple[float, float]], velocity: tuple[float, float]):
        self.start_xy = start
        self.velocity = np.array(velocity)

    def start(self, world: World) -> None:
        for xy in self.start_xy:
            spec = PersonSpec("adult", 1.75, 0.25, 0.0, 0.0, 1.2)
            world.add_person(spec, np.array(xy))

    def update(self, world: World, t: float) -> None:
        world.v_des[world.slots] = self.velocity


@pytest.mark.parametrize(
    ("velocity", "check"),
    [((1.5, 0.0), "obstacle"), ((0.0, -1.5), "wall")],
    ids=["into-obstacle", "into-wall"],
)
def test_people_pushed_into_furniture_or_walls_stop_at_them(
    velocity: tuple[float, float], check: str
) -> None:
    room = Room(10.0, 10.0, obstacles=(Obstacle("pillar", 5.0, 4.0, 6.0, 6.0, 2.5),))
    world = World(room, _Push([(2.0, 5.0)], velocity), _rng(0))
    for _ in range(250):
        world.step()
        x, y = world.pos[0]
        assert x <= 5.0 - 0.25 + 1e-9 or not 4.0 - 0.25 < y < 6.0 + 0.25
        assert y >= 0.25 - 1e-9
    x, y = world.pos[0]
    if check == "obstacle":
        assert 4.5 < x <= 4.75 + 1e-9 and y == pytest.approx(5.0, abs=0.05)
    else:
        assert y == pytest.approx(0.25, abs=0.05) and x == pytest.approx(2.0, abs=0.05)
    assert np.linalg.norm(world.vel[0]) < 0.2


def test_two_people_walking_into_each_other_do_not_pass_through() -> None:
    world = World(Room(10.0, 10.0), _Push([(2.0, 5.0)], (1.2, 0.0)), _rng(0))
    world.add_person(PersonSpec("adult", 1.75, 0.25, 0.0, 0.0, 1.2), np.array([8.0, 5.0]))

    class Both:
        def update(self, w: World, t: float) -> None:
            w.v_des[0] = (1.2, 0.0)
            w.v_des[1] = (-1.2, 0.0)

    world.director = Both()  # type: ignore[assignment]
    for _ in range(400):
        world.step()
    # pushed towards each other head-on they stay apart rather than swapping places
    assert world.pos[0, 0] < world.pos[1, 0]
    assert world.pos[1, 0] - world.pos[0, 0] > 0.3


def _crowd_min_ratios(seeds: Sequence[int], duration_s: float) -> np.ndarray:
    ratios = []
    for seed in seeds:
        sim = Simulator(_without_sensors(build_scenario("crowd", seed=seed)))
        world = sim.world
        for _ in range(int(duration_s / world.dt)):
            world.step()
            idx = world.slots
            pos, r = world.pos[idx], world.radius[idx]
            gap = np.linalg.norm(pos[:, None] - pos[None], axis=2)
            np.fill_diagonal(gap, np.inf)
            ratios.append((gap / (r[:, None] + r[None])).min())
    return np.array(ratios)


@pytest.fixture(scope="module")
def crowd_ratios() -> np.ndarray:
    return _crowd_min_ratios([0, 1, 2], 30.0)


def test_crowd_people_rarely_interpenetrate(crowd_ratios) -> None:
    # nobody walks through anybody, and bodies overlap markedly only now and then
    assert crowd_ratios.min() > 0.5
    assert np.mean(crowd_ratios < 0.8) < 0.05
    assert np.mean(crowd_ratios < 1.0) < 0.15


def test_crowd_people_never_overlap_deeply(crowd_ratios) -> None:
    assert crowd_ratios.min() > 0.8


def test_world_interpolates_between_steps() -> None:
    scenario = build_scenario("distance", seed=0, duration_s=5.0)
    world = Simulator(_without_sensors(scenario)).world
    world.advance_to(2.0)
    a = world.snapshot()
    world.step()
    b = world.snapshot()
    mid = world.state_at(a.t + 0.25 * (b.t - a.t))
    assert mid.pos == pytest.approx(0.75 * a.pos + 0.25 * b.pos)
    with pytest.raises(ValueError):
        world.state_at(a.t - 0.5)


# =============================================================== 7. live player


def test_live_player_publishes_every_event_on_a_memory_bus() -> None:
    sensors = [
        SensorConfig(id="k_a", type="kinect2", pose=_pose(0.2, 0.2, 2.6, 45.0, 22.0)),
        SensorConfig(
            id="k_b", type="sr4500", pose=_pose(9.8, 0.2, 2.6, 135.0, 22.0), clock_offset_s=1.5
        ),
    ]
    cfg = NetworkConfig(
        sensors=sensors,
        sim=SimConfig(scenario="crowd", seed=7, duration_s=1.5, speed=20.0),
    )
    scenario = scenario_from_network(cfg)
    assert [s.id for s in scenario.sensors] == ["k_a", "k_b"]
    assert cfg.sim is not None
    offline = _events(scenario, ground_truth_rate_hz=cfg.sim.ground_truth_rate_hz)

    bus = MemoryBus()
    received: list[tuple[str, bytes]] = []
    bus.subscribe("opt/default/detections/*", lambda s: received.append((s.key, s.payload)))
    bus.subscribe("opt/default/ground_truth", lambda s: received.append((s.key, s.payload)))
    node = Node("sim", bus, stats_interval_s=0)
    player = LivePlayer(
        scenario,
        node,
        speed=cfg.sim.speed,
        ground_truth_rate_hz=cfg.sim.ground_truth_rate_hz,
        max_capture_lag_s=None,  # a loaded machine must not drop frames here
    )
    player.run()
    node.close()
    bus.close()

    batches: dict[str, list] = defaultdict(list)
    truth = []
    for key, payload in received:
        if key == "opt/default/ground_truth":
            truth.append(decode_ground_truth(payload))
        else:
            batch = decode_detection_batch(payload)
            assert key == f"opt/default/detections/{batch.sensor_id}"
            batches[batch.sensor_id].append(batch)
    expected: dict[str, list] = defaultdict(list)
    for e in offline:
        if isinstance(e, SensorFrame):
            expected[e.batch.sensor_id].append(e.batch)
    assert set(batches) == {"k_a", "k_b"}
    for sensor_id, got in batches.items():
        want = expected[sensor_id]
        assert [b.seq for b in got] == list(range(len(want)))
        assert [len(b.detections) for b in got] == [len(b.detections) for b in want]
        for g, w in zip(got, want, strict=True):
            got_xy = [v for d in g.detections for v in (d.x, d.y)]
            assert got_xy == pytest.approx([v for d in w.detections for v in (d.x, d.y)], abs=1e-3)
        # stamps keep the frame spacing (live runs start at the wall clock)
        rate = next(s.rate_hz for s in scenario.sensors if s.id == sensor_id)
        stamps = np.array([b.stamp for b in got])
        assert np.diff(stamps) == pytest.approx(1.0 / rate, abs=1e-3)
    assert len(expected["k_a"]) in (45, 46)
    assert [t.seq for t in truth] == list(range(int(1.5 * 30) + 1))
    assert all(len(t.people) == 7 for t in truth)
    assert node.counters.get("detections") == sum(
        len(b.detections) for got in batches.values() for b in got
    )


def test_live_player_stops_when_the_node_stops() -> None:
    scenario = build_scenario("distance", seed=0, duration_s=None)
    bus = MemoryBus()
    node = Node("sim", bus, stats_interval_s=0)
    count = 0

    def on_truth(_sample: object) -> None:
        nonlocal count
        count += 1
        if count == 10:
            node.stop()

    bus.subscribe("opt/default/ground_truth", on_truth)
    LivePlayer(scenario, node, speed=50.0).run()  # returns although the scenario never ends
    node.close()
    bus.close()
    assert count == 10


def test_a_player_that_cannot_keep_up_skips_frames_instead_of_sending_them_late() -> None:
    scenario = build_scenario("stress", seed=3, duration_s=2.0)
    bus = MemoryBus()
    got: list[tuple[float, DetectionBatch]] = []
    bus.subscribe(
        "opt/default/detections/*",
        lambda s: got.append((time.time(), decode_detection_batch(s.payload))),
    )
    node = Node("sim", bus, stats_interval_s=0)
    start = time.time() + 1.0  # set-up time: the first frames are on time
    # 20x real time: 6000 frames/s of 120 people cannot be simulated that fast
    LivePlayer(scenario, node, speed=20.0, start_time=start).run()
    skipped = node.counters.get("skipped")
    node.close()
    bus.close()
    frames = sum(round(2.0 * s.rate_hz) for s in scenario.sensors)
    assert 0 < skipped < frames
    by_sensor: dict[str, list[int]] = defaultdict(list)
    for _, batch in got:
        by_sensor[batch.sensor_id].append(batch.seq)
    for seqs in by_sensor.values():  # what is sent is in order, with gaps where frames went
        assert seqs == sorted(set(seqs))
    assert len(got) + skipped <= frames
