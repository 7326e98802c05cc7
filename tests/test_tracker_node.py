"""The tracker node as a real process: tracks out, live reconfiguration, bad input."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from openptrack_py.config import ZenohConfig
from openptrack_py.messages import (
    Detection,
    DetectionBatch,
    TrackBatch,
    decode_track_batch,
    encode_detection_batch,
)
from openptrack_py.transport import wait_for_subscribers
from openptrack_py.transport.zenoh_bus import ZenohBus
from tests.conftest import ROOT, free_port, python_env, start_tracker, stop_process, wait_for

pytestmark = pytest.mark.zenoh


class Client:
    """This test's own Zenoh session: publishes detections, collects tracks."""

    def __init__(self, endpoint: str) -> None:
        cfg = ZenohConfig(hub=None, connect=[endpoint], listen=[], multicast_scouting=False)
        self.bus = ZenohBus(cfg)
        self.tracks: list[TrackBatch] = []
        self.lock = threading.Lock()
        self.bus.subscribe("opt/default/tracks", self._on_tracks)
        self.pub = self.bus.publisher("opt/default/detections/k1")
        self.raw = self.bus.publisher("opt/default/detections/k2")
        self.seq = 0

    def _on_tracks(self, sample: object) -> None:
        with self.lock:
            self.tracks.append(decode_track_batch(sample.payload))  # type: ignore[attr-defined]

    def received(self) -> list[TrackBatch]:
        with self.lock:
            return list(self.tracks)

    def send(self, *xy: tuple[float, float]) -> None:
        dets = tuple(
            Detection(x=x, y=y, z=0.9, height=1.7, confidence=0.9, distance=3.0) for x, y in xy
        )
        self.pub.put(
            encode_detection_batch(DetectionBatch("k1", self.seq, time.time(), "world", dets))
        )
        self.seq += 1


@pytest.fixture
def tracker_node(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[str], Client, str, Path]]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    net = tmp_path / "net.yaml"
    net.write_text("site: default\nzenoh: {hub: null}\ntracker: {reorder_window_s: 0.0}\n")
    log = tmp_path / "tracker.log"
    proc = start_tracker(net, endpoint, log)
    client = Client(endpoint)
    try:
        assert wait_for_subscribers(client.pub, timeout_s=30), log.read_text()
        yield proc, client, endpoint, log
    finally:
        client.bus.close()
        stop_process(proc)


def _config(endpoint: str, *assignments: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "openptrack_py.cli", "config", "tracker", *assignments,
         "-e", endpoint, "--no-multicast-scouting", "--format", "json", "--timeout", "20"],
        capture_output=True, text=True, timeout=60, env=python_env(), cwd=ROOT,
    )  # fmt: skip


def _sender(client: Client, stop: threading.Event, positions: Callable[[int], list]) -> None:
    i = 0
    while not stop.is_set():
        client.send(*positions(i))
        i += 1
        time.sleep(1 / 30)


def test_one_person_becomes_one_confirmed_track(tracker_node: tuple) -> None:
    _proc, client, _endpoint, _log = tracker_node
    for i in range(45):  # 0.9 m: a track is confirmed once its person has moved
        client.send((1.0 + 0.02 * i, 2.0))
        time.sleep(1 / 30)
    wait_for(lambda: any(b.tracks for b in client.received()), 10, "a published track")
    batches = client.received()
    ids = {t.id for b in batches for t in b.tracks}
    assert ids == {1}
    last = batches[-1].tracks[0]
    assert last.x == pytest.approx(1.88, abs=0.1) and last.y == pytest.approx(2.0, abs=0.05)
    assert last.vx == pytest.approx(0.6, abs=0.25)  # 0.02 m per 1/30 s
    # tracks are published once per step, in order
    seqs = [b.seq for b in batches]
    assert seqs == sorted(seqs)


def test_live_change_applies_on_the_next_step_and_bad_ones_are_refused(
    tracker_node: tuple,
) -> None:
    proc, client, endpoint, log = tracker_node
    stop = threading.Event()
    # every frame a detection far from all others: it starts a tentative track each time
    sender = threading.Thread(
        target=_sender,
        args=(client, stop, lambda i: [(3.0 * (i % 7), 4.0 * (i % 5))]),
        daemon=True,
    )
    sender.start()
    try:
        wait_for(lambda: len(client.received()) > 10, 10, "steps with tentative tracks")
        # tentative: not published, nor listed alive
        assert all(not b.tracks and not b.alive_ids for b in client.received())

        result = _config(endpoint, "publish_tentative=true")
        assert result.returncode == 0, result.stderr
        ack = json.loads(result.stdout)
        assert ack["accepted"] and ack["config"]["publish_tentative"] is True
        seen_at_ack = len(client.received())
        wait_for(lambda: len(client.received()) > seen_at_ack + 5, 10, "more steps")
        after = client.received()[seen_at_ack:]
        assert any(b.tracks for b in after)
        assert all(not t.confirmed for b in after for t in b.tracks)
        assert all(b.alive_ids == tuple(t.id for t in b.tracks) for b in after)

        bad = _config(endpoint, "gate_probability=1.5")
        assert bad.returncode == 2
        refusal = json.loads(bad.stdout)
        assert not refusal["accepted"]
        assert "gate_probability: must be <= 0.99999 (received 1.5)" in refusal["error"]
        assert refusal["config"]["gate_probability"] == 0.99  # unchanged
        unknown = _config(endpoint, "gate_probabilty=0.9")
        assert unknown.returncode == 2
        assert "did you mean 'gate_probability'?" in json.loads(unknown.stdout)["error"]
        fixed = _config(endpoint, "host=elsewhere")
        assert fixed.returncode == 2 and "cannot be changed while running" in fixed.stdout

        count = len(client.received())
        wait_for(lambda: len(client.received()) > count + 5, 10, "the node to keep stepping")
        assert proc.poll() is None
    finally:
        stop.set()
        sender.join()
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=15) == 0
    text = log.read_text()
    assert "config_applied=1" in text and "config_rejected=3" in text


def test_malformed_input_and_a_dead_publisher_do_not_stop_the_tracker(
    tracker_node: tuple, tmp_path: Path
) -> None:
    proc, client, endpoint, log = tracker_node
    for payload in (b"", b"{", b'{"v":1,"kind":"detections"}', b"\x00" * 1000):
        client.raw.put(payload)
    # a second publisher process that dies abruptly mid-stream
    script = (
        "import time, sys\n"
        "from tests.procs.publisher import batch\n"
        "from openptrack_py.config import ZenohConfig\n"
        "from openptrack_py.transport import wait_for_subscribers\n"
        "from openptrack_py.transport.zenoh_bus import ZenohBus\n"
        f"bus = ZenohBus(ZenohConfig(hub=None, connect=['{endpoint}'], listen=[]))\n"
        "pub = bus.publisher('opt/default/detections/k9')\n"
        "wait_for_subscribers(pub, 20)\n"
        "for i in range(10**6):\n"
        "    pub.put(batch(i)); time.sleep(0.01)\n"
    )
    victim = subprocess.Popen(
        [sys.executable, "-c", script], env=python_env(), cwd=ROOT, stderr=subprocess.DEVNULL
    )
    time.sleep(2.0)
    victim.kill()  # SIGKILL: no goodbye on the wire
    victim.wait()
    count = len(client.received())
    for i in range(30):
        client.send((2.0, 2.0 + 0.01 * i))
        time.sleep(1 / 30)
    wait_for(lambda: len(client.received()) >= count + 30, 10, "a step per batch after the death")
    assert proc.poll() is None
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=15) == 0
    assert "malformed=4" in log.read_text()


# ------------------------------------------------------------------------ frames


def _frame_batches(
    sent: list[tuple[str, str]], sensors: list[dict]
) -> tuple[list[TrackBatch], int]:
    """Feed one person as ``(sensor, frame)`` batches to a tracker of a network of
    ``sensors``; the tracks and the batches dropped for their frame."""
    from openptrack_py.config import NetworkConfig, TrackerConfig
    from openptrack_py.runtime.node import Node
    from openptrack_py.tracking.service import TrackerService
    from openptrack_py.transport.memory import MemoryBus, MemoryNetwork

    network = NetworkConfig(sensors=sensors)
    net = MemoryNetwork()
    sender = MemoryBus(net)
    tracks: list[TrackBatch] = []
    with MemoryBus(net) as bus, Node("tracker", bus, stats_interval_s=0) as node:
        service = TrackerService(node, TrackerConfig(reorder_window_s=0.0), network)
        sender.subscribe(
            "opt/default/tracks", lambda s: tracks.append(decode_track_batch(s.payload))
        )
        t0 = time.time()
        for k, (sensor, frame) in enumerate(sent):
            det = Detection(
                x=2.0 + 0.03 * k, y=1.0, z=0.9, height=1.7, confidence=0.9, distance=3.0
            )
            batch = DetectionBatch(sensor, k, t0 + k / 30, frame, (det,))
            sender.put(f"opt/default/detections/{sensor}", encode_detection_batch(batch))
            service.step_once(timeout_s=0.05)
        return tracks, node.counters.get("wrong_frame")


CAM = {"id": "cam", "source": "camera"}  # no pose: it reports in its own floor frame
POSED = {"id": "a", "source": "camera", "pose": {"x": 0.0, "y": 0.0}}


def test_a_sensor_without_pose_is_tracked_alone_in_its_own_frame() -> None:
    tracks, dropped = _frame_batches([("cam", "cam")] * 30, [CAM])
    assert dropped == 0
    assert tracks and {t.frame_id for t in tracks} == {"cam"}
    assert any(t.tracks for t in tracks)


def test_batches_in_another_frame_are_counted_and_never_fused() -> None:
    sent = [("a", "world")] * 6 + [("cam", "cam"), ("a", "world")] * 2
    tracks, dropped = _frame_batches(sent, [POSED, CAM])
    assert dropped == 2
    assert {t.frame_id for t in tracks} == {"world"}


def test_an_uncalibrated_sensor_speaking_first_does_not_lock_the_frame() -> None:
    sent = [("cam", "cam")] * 3 + [("a", "world")] * 30
    tracks, dropped = _frame_batches(sent, [POSED, CAM])
    assert dropped == 3
    assert {t.frame_id for t in tracks} == {"world"} and any(t.tracks for t in tracks)


def test_a_tracker_that_fell_behind_tracks_only_each_sensors_newest_batch() -> None:
    """Batches of one sensor waiting together: the newest is tracked, the rest superseded,
    and every step's tracks are published (the other sensor's batch is not touched)."""
    from openptrack_py.config import NetworkConfig, TrackerConfig
    from openptrack_py.runtime.node import Node
    from openptrack_py.tracking.service import TrackerService
    from openptrack_py.transport.memory import MemoryBus, MemoryNetwork

    network = NetworkConfig(sensors=[POSED, {**POSED, "id": "b"}])
    net = MemoryNetwork()
    sender = MemoryBus(net)
    tracks: list[TrackBatch] = []
    with MemoryBus(net) as bus, Node("tracker", bus, stats_interval_s=0) as node:
        service = TrackerService(
            node, TrackerConfig(reorder_window_s=0.0, clock_correction="none"), network
        )
        sender.subscribe(
            "opt/default/tracks", lambda s: tracks.append(decode_track_batch(s.payload))
        )
        t0 = time.time()
        det = Detection(x=2.0, y=1.0, z=0.9, height=1.7, confidence=0.9, distance=3.0)
        for k, sensor in enumerate(["a", "b", "a", "a"]):
            batch = DetectionBatch(sensor, k, t0 + k / 30, "world", (det,))
            sender.put(f"opt/default/detections/{sensor}", encode_detection_batch(batch))
        assert service.step_once(timeout_s=0.05) == 2
        assert node.counters.get("superseded") == 2
        assert [round(b.stamp - t0, 3) for b in tracks] == [round(1 / 30, 3), round(3 / 30, 3)]


@pytest.mark.parametrize("discover", [False, True], ids=["listed-only", "discovering"])
def test_the_reorder_window_never_waits_for_a_sensor_the_network_does_not_list(
    discover: bool,
) -> None:
    """An unlisted sensor speaking once a second: refused, so the listed sensor's batches
    are tracked at once; a network that discovers sensors waits for it (the contrast)."""
    from openptrack_py.config import NetworkConfig, TrackerConfig
    from openptrack_py.runtime.node import Node
    from openptrack_py.tracking.service import TrackerService
    from openptrack_py.transport.memory import MemoryBus, MemoryNetwork

    network = NetworkConfig(sensors=[POSED])
    config = TrackerConfig(
        reorder_window_s=2.0, discover_sensors=discover, clock_correction="none"
    )
    net = MemoryNetwork()
    sender = MemoryBus(net)
    det = Detection(x=2.0, y=1.0, z=0.9, height=1.7, confidence=0.9, distance=3.0)
    with MemoryBus(net) as bus, Node("tracker", bus, stats_interval_s=0) as node:
        service = TrackerService(node, config, network)
        t0 = time.time()
        for k, (sensor, stamp) in enumerate([("x", t0), ("x", t0 + 0.05), ("a", t0 + 0.95)]):
            sender.put(
                f"opt/default/detections/{sensor}",
                encode_detection_batch(DetectionBatch(sensor, k, stamp, "world", (det,))),
            )
            steps = service.step_once(timeout_s=0.05)
    assert steps == (0 if discover else 1)
