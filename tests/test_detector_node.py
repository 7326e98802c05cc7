"""The detector node: where it runs, dropping stale frames, recordings and rendered sensors.

Frames are rendered by :mod:`openptrack_py.sim.render` from people standing at known
places, so every published detection can be checked against where they really are.
"""

from __future__ import annotations

import dataclasses
import itertools
import re
import signal
import subprocess
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from openptrack_py.config import (
    DetectorConfig,
    NetworkConfig,
    Pose,
    SensorConfig,
    ZenohConfig,
    load_network,
)
from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.detection.service import DetectorService
from openptrack_py.launch import plan_nodes
from openptrack_py.messages import (
    Detection,
    DetectionBatch,
    GroundTruthFrame,
    TrackBatch,
    decode_detection_batch,
    decode_ground_truth,
    decode_track_batch,
)
from openptrack_py.runtime.node import Node
from openptrack_py.sim.live import scenario_from_network
from openptrack_py.sim.render import DepthRenderer
from openptrack_py.sim.scenarios import scenario_world
from openptrack_py.sim.sensors import SensorSpec
from openptrack_py.sim.world import Room, Snapshot
from openptrack_py.transport import MemoryBus, Sample
from openptrack_py.transport.zenoh_bus import ZenohBus
from tests.conftest import ROOT, free_port, people_snapshot, python_env, wait_for

DEMO = ROOT / "config" / "demo.yaml"
POSE = Pose(x=0.2, y=4.0, z=2.6, yaw_deg=0.0, pitch_deg=22.0)
ROOM = Room(10.0, 8.0)
# (x, y, height, radius, top hue, bottom hue) of two people standing still
PEOPLE = ((3.0, 3.3, 1.75, 0.22, 10.0, 200.0), (4.5, 5.0, 1.65, 0.20, 120.0, 60.0))
PEOPLE_XY = np.array([p[:2] for p in PEOPLE])
STAMP0 = 1_700_000_000.0
PERIOD = 1 / 30
# The crowd scenario's own sensor layout (openptrack_py.sim.scenarios._crowd).
CROWD_SENSORS = [
    {"id": "k2_a", "type": "kinect2", "pose": {"x": 0.2, "y": 0.2, "z": 2.6, "yaw_deg": 45.0,
                                              "pitch_deg": 22.0}},
    {"id": "k2_b", "type": "kinect2", "pose": {"x": 9.8, "y": 0.2, "z": 2.6, "yaw_deg": 135.0,
                                              "pitch_deg": 22.0}},
    {"id": "k2_c", "type": "kinect2", "pose": {"x": 5.0, "y": 9.8, "z": 2.6, "yaw_deg": -90.0,
                                              "pitch_deg": 22.0}},
]  # fmt: skip


# --------------------------------------------------------------------------- helpers


def _snapshot() -> Snapshot:
    return people_snapshot(PEOPLE)


def _rendered(n: int, seed: int = 0) -> list[Frame]:
    """``n`` noisy kinect2 captures of the two people, stamped at 30 Hz from STAMP0."""
    spec = SensorSpec.from_config(SensorConfig(id="cam", type="kinect2", pose=POSE))
    renderer = DepthRenderer(spec, ROOM, np.random.default_rng(seed))
    snap = _snapshot()
    return [renderer.render(snap, stamp=STAMP0 + i * PERIOD, seq=i).frame for i in range(n)]


def _finds_both_people(detections: Sequence[Detection], radius: float = 0.3) -> bool:
    """Exactly two detections, one within ``radius`` of each person (world frame)."""
    if len(detections) != len(PEOPLE_XY):
        return False
    found = np.array(sorted((d.x, d.y) for d in detections))
    truth = PEOPLE_XY[np.argsort(PEOPLE_XY[:, 0])]
    return bool((np.linalg.norm(found - truth, axis=1) <= radius).all())


class _Collector:
    """Decodes and keeps what arrives on a bus, per key, thread-safely."""

    def __init__(self, bus: Any, keyexpr: str, decode: Callable[[bytes], Any]) -> None:
        self.items: list[tuple[str, Any]] = []
        self._lock = threading.Lock()
        self._decode = decode
        bus.subscribe(keyexpr, self._on_sample)

    def _on_sample(self, sample: Sample) -> None:
        message = self._decode(sample.payload)
        with self._lock:
            self.items.append((sample.key, message))

    def messages(self) -> list[Any]:
        with self._lock:
            return [m for _, m in self.items]

    def keys(self) -> Counter[str]:
        with self._lock:
            return Counter(k for k, _ in self.items)


def _write_network(path: Path, data: dict[str, Any]) -> Path:
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _detector_cmd(net: Path, *args: str) -> list[str]:
    return [sys.executable, "-m", "openptrack_py.nodes.detector", "-c", str(net),
            "--no-multicast-scouting", *args]  # fmt: skip


def _spawn(cmd: list[str], log: Path) -> subprocess.Popen[str]:
    """Start ``cmd`` with its output (stdout and stderr) going to ``log``."""
    with log.open("w") as out:
        return subprocess.Popen(
            cmd, stdout=out, stderr=subprocess.STDOUT, text=True, env=python_env(), cwd=ROOT
        )


def _test_bus(*, listen: Sequence[str] = (), connect: Sequence[str] = ()) -> ZenohBus:
    cfg = ZenohConfig(
        hub=None, listen=list(listen), connect=list(connect), multicast_scouting=False
    )
    return ZenohBus(cfg)


def _stop(proc: subprocess.Popen[str]) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


# -------------------------------------------------------------------------- planning


def _names_and_sensors(specs: Sequence[Any]) -> list[tuple[str, str | None]]:
    out = []
    for spec in specs:
        args = list(spec.args)
        sensor = args[args.index("--sensor") + 1] if "--sensor" in args else None
        out.append((spec.name, sensor))
    return out


def test_rgbd_plans_one_detector_per_sim_sensor_on_the_sim_host_only() -> None:
    rgbd = load_network(DEMO, ["sim.sensor_model=rgbd", "sim.host=simbox"])
    on_sim = plan_nodes(rgbd, "simbox", DEMO)
    assert _names_and_sensors(on_sim) == [
        ("sim", None),
        ("detector_k2_a", "k2_a"),
        ("detector_k2_b", "k2_b"),
        ("detector_k2_c", "k2_c"),
    ]
    for spec in on_sim[1:]:
        assert spec.module == "openptrack_py.nodes.detector"
        assert spec.command()[3:5] == ["-c", str(DEMO)]
    # the tracker and output stay on their own (local) host, without detectors
    assert [s.name for s in plan_nodes(rgbd, "localhost", DEMO)] == ["tracker", "output"]
    assert plan_nodes(rgbd, "elsewhere", DEMO) == []

    detections = load_network(DEMO, ["sim.host=simbox"])
    assert detections.sim is not None and detections.sim.sensor_model == "detections"
    assert [s.name for s in plan_nodes(detections, "simbox", DEMO)] == ["sim"]


def test_a_camera_sensor_gets_its_detector_on_its_own_host() -> None:
    cfg = NetworkConfig.model_validate(
        {
            "sensors": [
                {"id": "cam", "type": "realsense", "source": "camera", "host": "other"},
                {"id": "rec", "source": "recording", "input": "/data/rec", "host": "third"},
            ],
            "tracker": {},
        }
    )
    assert _names_and_sensors(plan_nodes(cfg, "other", "net.yaml")) == [("detector_cam", "cam")]
    assert _names_and_sensors(plan_nodes(cfg, "third", "net.yaml")) == [("detector_rec", "rec")]
    assert [s.name for s in plan_nodes(cfg, "localhost", "net.yaml")] == ["tracker"]


# ----------------------------------------------------------- the service, in process


class _Burst:
    """A source that yields copies of a few rendered frames without ever sleeping.

    To make "detection is slower than the source" certain rather than likely, source and
    detector go in rounds: while one frame is being detected the source yields ``ahead``
    new ones, and the next round waits until the next detection starts.
    """

    name = "burst"

    def __init__(self, base: Sequence[Frame], count: int, ahead: int) -> None:
        self.base = list(base)
        self.intrinsics = base[0].intrinsics
        self.count = count
        self.ahead = ahead
        self.yielded: list[Frame] = []
        self.detections = 0
        self.done = False
        self.closed = False
        self.cond = threading.Condition()

    def frames(self) -> Iterator[Frame]:
        for i in range(self.count):
            frame = dataclasses.replace(
                self.base[i % len(self.base)], seq=i, stamp=STAMP0 + i * PERIOD
            )
            with self.cond:
                if i % self.ahead == 0:
                    self._wait(lambda n=i // self.ahead: self.detections >= n)
                self.yielded.append(frame)
                self.cond.notify_all()
            yield frame
        with self.cond:
            self.done = True
            self.cond.notify_all()

    def _wait(self, predicate: Callable[[], bool]) -> None:
        assert self.cond.wait_for(predicate, 30.0), "the detector and the source hung"

    def detecting(self) -> None:
        """Called as a detection starts: wait while the source runs ``ahead`` frames on."""
        with self.cond:
            self.detections += 1
            self.cond.notify_all()
            target = (self.detections + 1) * self.ahead
            self._wait(lambda: len(self.yielded) >= target or self.done)

    def close(self) -> None:
        self.closed = True


def test_service_detects_only_the_newest_frame_and_counts_the_rest_as_dropped() -> None:
    source = _Burst(_rendered(3), count=60, ahead=5)
    with MemoryBus() as bus, Node("detector_cam", bus, stats_interval_s=0) as node:
        got = _Collector(bus, "opt/default/detections/cam", decode_detection_batch)
        sensor = SensorConfig(id="cam", type="kinect2", source="recording", pose=POSE)
        service = DetectorService(node, sensor, DetectorConfig(), source)
        detect = service.detector.detect

        def slow_detect(frame: Frame) -> Any:
            source.detecting()
            return detect(frame)

        service.detector.detect = slow_detect  # type: ignore[method-assign]
        service.run()  # returns when the source ends
        stats = node.counters.snapshot()

    batches: list[DetectionBatch] = got.messages()
    assert source.closed
    assert len(batches) >= 10
    assert [b.seq for b in batches] == list(range(len(batches)))
    counters = stats.counters
    assert counters["frames_in"] == source.count
    assert counters["frames_dropped"] > 0
    assert counters["frames_in"] == counters["batches"] + counters["frames_dropped"]
    assert counters["batches"] == len(batches)
    assert {"cloud", "ground", "cluster"} <= set(stats.timings_ms)
    assert all(stats.timings_ms[s] > 0 for s in ("cloud", "ground", "cluster"))
    # newest frame wins: the last frame is always detected, and frames that came in
    # while detecting were skipped, not queued
    assert batches[-1].stamp == source.yielded[-1].stamp
    index = [round((b.stamp - STAMP0) / PERIOD) for b in batches]
    assert all(b.stamp == source.yielded[i].stamp for b, i in zip(batches, index, strict=True))
    assert all(later - earlier > 1 for earlier, later in itertools.pairwise(index[:-1]))
    for batch in batches:
        assert batch.sensor_id == "cam" and batch.frame_id == "world"
        assert _finds_both_people(batch.detections), batch.detections


class _Frames:
    """A source that yields its frames once, then ends."""

    name = "frames"

    def __init__(self, frames: Sequence[Frame]) -> None:
        self.list = list(frames)

    def frames(self) -> Iterator[Frame]:
        yield from self.list

    def close(self) -> None:
        pass


def test_service_detects_through_the_calibrated_pinhole_not_the_frames() -> None:
    """A unit whose lens is 4 % longer and centred 12 px off its type's, whose frames
    report the type's pinhole (as a camera's factory figures can be wrong): detected
    through what its frames say, both people are 12-13 cm off; through its calibrated
    pinhole (given at half the resolution: scaled to the frames'), within 2 cm; one of
    another image shape is not used."""
    nominal = Intrinsics.for_sensor("kinect2")
    own = Intrinsics(512, 424, nominal.fx * 1.04, nominal.fy * 1.04, nominal.cx + 12,
                     nominal.cy - 6)  # fmt: skip
    spec = SensorSpec.from_config(SensorConfig(id="cam", type="kinect2", pose=POSE))
    renderer = DepthRenderer(spec, ROOM, np.random.default_rng(1), intrinsics=own)
    frames = [
        dataclasses.replace(
            renderer.render(_snapshot(), stamp=STAMP0 + i * PERIOD, seq=i).frame,
            intrinsics=nominal,
        )
        for i in range(3)
    ]
    sensor = SensorConfig(id="cam", type="kinect2", source="recording", pose=POSE)
    errors = {}
    other_shape = Intrinsics(640, 480, 500.0, 500.0, 320.0, 240.0)  # another image mode
    cases = (("frames", None), ("calibrated", own.scaled(256, 212)), ("other", other_shape))
    for name, calibrated in cases:
        with MemoryBus() as bus, Node("detector_cam", bus, stats_interval_s=0) as node:
            got = _Collector(bus, "opt/default/detections/cam", decode_detection_batch)
            service = DetectorService(
                node, sensor, DetectorConfig(), _Frames(frames), intrinsics=calibrated
            )
            service.run()
        batches = got.messages()
        assert batches and all(len(b.detections) == 2 for b in batches), name
        xy = np.array([[(d.x, d.y) for d in b.detections] for b in batches])
        errors[name] = np.linalg.norm(xy[:, :, None] - PEOPLE_XY[None, None], axis=3).min(axis=2)
    assert errors["frames"].min() > 0.10, errors
    assert errors["calibrated"].max() < 0.02, errors
    # intrinsics of another image shape are not stretched onto these frames
    np.testing.assert_array_equal(errors["other"], errors["frames"])


# ------------------------------------------------------------------- node processes


@pytest.mark.zenoh
def test_detector_node_replays_a_recording_and_exits_when_it_ends(tmp_path: Path) -> None:
    from openptrack_py.detection.sources import record_folder

    frames = _rendered(10, seed=1)
    assert record_folder(frames, tmp_path / "rec") == 10
    net = _write_network(
        tmp_path / "net.yaml",
        {
            "zenoh": {"hub": None},
            "sensors": [
                {"id": "cam", "type": "kinect2", "source": "recording",
                 "input": str(tmp_path / "rec"), "pose": POSE.model_dump()},
            ],
        },
    )  # fmt: skip
    # The replay starts as soon as the node is up and is not paced, so the node connects
    # to this test's session (already subscribed) rather than the other way round.
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    bus = _test_bus(listen=[endpoint])
    try:
        got = _Collector(bus, "opt/default/detections/*", decode_detection_batch)
        log = tmp_path / "detector.log"
        proc = _spawn(_detector_cmd(net, "--sensor", "cam", "-e", endpoint), log)
        try:
            code = proc.wait(timeout=60)
        finally:
            _stop(proc)
        text = log.read_text()
        assert code == 0, text
        wait_for(lambda: got.messages(), 5, "detection batches")
        time.sleep(0.3)  # let the last samples in
    finally:
        bus.close()
    assert set(got.keys()) == {"opt/default/detections/cam"}
    batches: list[DetectionBatch] = got.messages()
    stamps = [f.stamp for f in frames]
    assert "detector_cam: detecting sensor=cam" in text and "frames_in=10" in text
    assert re.search(rf"\bbatches={len(batches)}\b", text)  # every published batch arrived
    assert [b.seq for b in batches] == list(range(len(batches)))
    assert batches[-1].stamp == pytest.approx(stamps[-1], abs=1e-6)
    for batch in batches:
        assert batch.frame_id == "world"
        assert min(abs(batch.stamp - s) for s in stamps) < 1e-6
        assert _finds_both_people(batch.detections), batch.detections


@pytest.mark.zenoh
@pytest.mark.parametrize(
    ("sensor", "expected"),
    [
        (
            {"id": "cam", "source": "recording", "input": "/nonexistent"},
            ["sensors.cam", "'/nonexistent'", "no such file or folder"],
        ),
        (
            {"id": "cam", "type": "kinect2", "source": "camera"},
            ["sensors.cam.input", "a camera sensor needs an input"],
        ),
    ],
    ids=["missing-input", "no-input"],
)
def test_detector_node_without_frames_exits_2_naming_sensor_and_input(
    tmp_path: Path, sensor: dict[str, str], expected: list[str]
) -> None:
    net = _write_network(tmp_path / "net.yaml", {"zenoh": {"hub": None}, "sensors": [sensor]})
    result = subprocess.run(
        _detector_cmd(net, "--sensor", "cam"),
        capture_output=True, text=True, timeout=60, env=python_env(), cwd=ROOT,
    )  # fmt: skip
    assert result.returncode == 2, result.stdout + result.stderr
    assert "Traceback" not in result.stderr
    for part in expected:
        assert part in result.stderr


@pytest.mark.zenoh
def test_rendering_detector_sees_the_shared_world_and_stops_on_sigint(tmp_path: Path) -> None:
    start = time.time() + 1.0
    data = {
        "zenoh": {"hub": None},
        "sensors": CROWD_SENSORS[:1],
        "sim": {"scenario": "crowd", "sensor_model": "rgbd", "seed": 0, "start_time": start},
        "detector": {"rate_hz": 5},
    }
    net = _write_network(tmp_path / "net.yaml", data)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    bus = _test_bus(listen=[endpoint])
    log = tmp_path / "detector.log"
    proc = _spawn(_detector_cmd(net, "--sensor", "k2_a", "-e", endpoint), log)
    try:
        got = _Collector(bus, "opt/default/detections/k2_a", decode_detection_batch)
        wait_for(lambda: len(got.messages()) >= 10, 60, "10 batches from the rendering detector")
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=20)
    finally:
        _stop(proc)
        bus.close()
    text = log.read_text()
    assert code == 0, text
    assert "stopping signal=SIGINT" in text
    batches: list[DetectionBatch] = got.messages()
    assert all(b.frame_id == "world" for b in batches)
    # captures at the detector's rate on the scenario's clock, never repeated
    gaps = np.diff([b.stamp for b in batches])
    assert (gaps > 0).all() and np.allclose(gaps / 0.2, np.round(gaps / 0.2), atol=0.01)
    # every detection is someone of the world the simulator plays from the same start
    scenario = scenario_from_network(load_network(net))
    world = scenario_world(scenario)
    near = total = 0
    for batch in batches:
        snap = world.state_at(batch.stamp - start)
        for d in batch.detections:
            total += 1
            near += np.hypot(*(snap.pos - (d.x, d.y)).T).min() <= 0.3
    assert total >= 2 * len(batches)  # the crowd stays in front of this sensor
    assert near >= 0.9 * total, (near, total)


@pytest.mark.zenoh
@pytest.mark.slow
def test_launch_rgbd_tracks_follow_the_ground_truth(tmp_path: Path) -> None:
    hub = f"tcp/127.0.0.1:{free_port()}"
    data = {
        "site": "default",
        "zenoh": {"hub": hub, "listen": ["tcp/127.0.0.1:0"], "multicast_scouting": False},
        "sensors": CROWD_SENSORS,
        "sim": {"scenario": "crowd", "sensor_model": "rgbd", "seed": 0,
                "ground_truth_rate_hz": 10},
        "detector": {"rate_hz": 8},
        "tracker": {},
    }  # fmt: skip
    net = _write_network(tmp_path / "net.yaml", data)
    log = tmp_path / "launch.log"
    launch = ["-m", "openptrack_py.cli", "launch", str(net), "--duration", "14"]
    proc = _spawn([sys.executable, *launch, "--status-interval", "0"], log)
    bus = None
    try:
        wait_for(lambda: "hub listening on" in log.read_text(), 30, "the launcher's hub")
        bus = _test_bus(connect=[hub])
        tracks = _Collector(bus, "opt/default/tracks", decode_track_batch)
        truth = _Collector(bus, "opt/default/ground_truth", decode_ground_truth)
        detections = _Collector(bus, "opt/default/detections/*", decode_detection_batch)
        code = proc.wait(timeout=90)
    finally:
        _stop(proc)
        if bus is not None:
            bus.close()
    text = log.read_text()
    assert code == 0, text[-3000:]
    assert "starting sim, detector_k2_a, detector_k2_b, detector_k2_c, tracker" in text
    for sensor in ("k2_a", "k2_b", "k2_c"):
        assert detections.keys()[f"opt/default/detections/{sensor}"] >= 20, detections.keys()
    assert all(b.frame_id == "world" for b in detections.messages())

    batches: list[TrackBatch] = tracks.messages()
    frames: list[GroundTruthFrame] = truth.messages()
    assert batches and frames, text[-3000:]
    track_stamps = np.array([b.stamp for b in batches])
    late = [f for f in frames if f.stamp >= frames[-1].stamp - 5.0]
    assert len(late) >= 30
    covered = pairs = true_tracks = confirmed = 0
    for frame in late:
        nearest = int(np.argmin(np.abs(track_stamps - frame.stamp)))
        if abs(track_stamps[nearest] - frame.stamp) > 0.2:
            continue
        xy = np.array([(t.x, t.y) for t in batches[nearest].tracks if t.confirmed]).reshape(-1, 2)
        people = np.array([(p.x, p.y) for p in frame.people]).reshape(-1, 2)
        # distance from every confirmed track to every person
        gap = np.linalg.norm(xy[:, None, :] - people[None, :, :], axis=2)
        confirmed += len(xy)
        true_tracks += int((gap <= 0.5).any(axis=1).sum())
        for j, person in enumerate(frame.people):
            if person.covered:
                pairs += 1
                covered += bool((gap[:, j] <= 0.5).any())
    assert pairs >= 100, pairs
    assert covered >= 0.8 * pairs, (covered, pairs)
    assert true_tracks >= 0.8 * confirmed, (true_tracks, confirmed)  # few phantom tracks
