"""The fault suite: hostile or unlucky input against a real tracker process over Zenoh.

A real sensor (``a``) sees one person walking a loop at 30 Hz while an attacker (or a
broken peer) publishes well-formed but harmful batches. Each test asserts that the
refusal is counted, that the person's confirmed track keeps flowing (during the attack
or within a second of its end), and, for the floods, that the tracker's memory comes
back to its baseline.
"""

from __future__ import annotations

import math
import re
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
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
from openptrack_py.messages.codec import decode_node_stats
from openptrack_py.transport import wait_for_subscribers
from openptrack_py.transport.zenoh_bus import ZenohBus
from tests.conftest import free_port, start_tracker, stop_process, wait_for

pytestmark = [pytest.mark.zenoh, pytest.mark.slow]

NETWORK = """\
site: default
zenoh: {hub: null}
stats_interval_s: 0.5
sensors:
  - {id: a, source: camera, pose: {x: 0.0, y: 0.0}}
  - {id: b, source: camera, pose: {x: 8.0, y: 0.0, yaw_deg: 180}}
  - {id: cam, source: camera}
tracker: {reorder_window_s: 0.0}
"""
"""Two calibrated sensors and one without a pose (it reports in its own frame)."""


def person_at(t: float) -> tuple[float, float]:
    """A person walking a 1.5 m circle around (4, 3), once every 8 s."""
    return 4.0 + 1.5 * math.cos(t * math.pi / 4), 3.0 + 1.5 * math.sin(t * math.pi / 4)


def _det(x: float, y: float, conf: float = 0.9) -> Detection:
    return Detection(x=x, y=y, z=0.9, height=1.7, confidence=conf, distance=4.0)


@dataclass
class Rig:
    """The tracker process, this test's Zenoh session, and the real sensor's thread."""

    proc: subprocess.Popen[str]
    log: Path
    bus: ZenohBus
    tracks: list[tuple[float, TrackBatch]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)
    stop: threading.Event = field(default_factory=threading.Event)
    stats: dict[str, int] = field(default_factory=dict)

    def on_tracks(self, sample: object) -> None:
        batch = decode_track_batch(sample.payload)  # type: ignore[attr-defined]
        with self.lock:
            self.tracks.append((time.time(), batch))

    def on_stats(self, sample: object) -> None:
        stats = decode_node_stats(sample.payload)  # type: ignore[attr-defined]
        with self.lock:
            self.stats = dict(stats.counters)

    def publisher(self, sensor: str) -> object:
        return self.bus.publisher(f"opt/default/detections/{sensor}")

    def sense(self) -> None:
        """The real sensor: one batch of the person every frame."""
        pub = self.publisher("a")
        k = 0
        while not self.stop.is_set():
            now = time.time()
            batch = DetectionBatch("a", k, now, "world", (_det(*person_at(now)),))
            pub.put(encode_detection_batch(batch))  # type: ignore[attr-defined]
            k += 1
            time.sleep(1 / 30)

    def person_tracked_since(self, since: float) -> bool:
        """Whether a confirmed track within 0.5 m of the person came out after ``since``."""
        with self.lock:
            recent = [(t, b) for t, b in self.tracks if t >= since]
        for _, batch in recent:
            x, y = person_at(batch.stamp)
            if any(tr.confirmed and math.hypot(tr.x - x, tr.y - y) < 0.5 for tr in batch.tracks):
                return True
        return False

    def counter(self, name: str) -> int:
        """The tracker's latest published value of a counter (its stats)."""
        with self.lock:
            return self.stats.get(name, 0)

    def rss_mib(self) -> float:
        """The tracker's private resident memory (``RssAnon``), MiB.

        Shared memory (``RssShmem``) is counted apart; Zenoh's is off in these sessions.
        """
        text = Path(f"/proc/{self.proc.pid}/status").read_text()
        return int(re.search(r"RssAnon:\s+(\d+)", text).group(1)) / 1024  # type: ignore[union-attr]


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[Rig]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    net = tmp_path / "net.yaml"
    net.write_text(NETWORK)
    log = tmp_path / "tracker.log"
    proc = start_tracker(net, endpoint, log)
    bus = ZenohBus(ZenohConfig(hub=None, connect=[endpoint], listen=[], multicast_scouting=False))
    rig = Rig(proc, log, bus)
    bus.subscribe("opt/default/tracks", rig.on_tracks)
    bus.subscribe("opt/default/stats/tracker", rig.on_stats)
    sensor = threading.Thread(target=rig.sense, daemon=True)
    try:
        probe = rig.publisher("a")
        assert wait_for_subscribers(probe, timeout_s=30), log.read_text()  # type: ignore[arg-type]
        sensor.start()
        wait_for(lambda: rig.person_tracked_since(0.0), 15, "the person's confirmed track")
        yield rig
    finally:
        rig.stop.set()
        if sensor.is_alive():
            sensor.join(5)
        bus.close()
        stop_process(proc)


def _attack(
    rig: Rig, seconds: float, each: Callable[[int, float], None], period: float
) -> tuple[float, int]:
    """Run ``each(k, now)`` every ``period`` for ``seconds``; return when it stopped and
    how many times it ran (fewer than ``seconds / period`` on a busy machine)."""
    end = time.time() + seconds
    k = 0
    while time.time() < end:
        each(k, time.time())
        k += 1
        if period > 0:
            time.sleep(period)
    return time.time(), k


def _most_of(sent: int) -> int:
    """All but a sixth of ``sent`` messages: each is counted, bar the first few."""
    return sent - sent // 6


def _still_tracked(rig: Rig, stopped: float) -> None:
    wait_for(lambda: rig.person_tracked_since(stopped), 1.5, "the person within 1 s")
    assert rig.proc.poll() is None


def test_a_batch_stamped_far_in_the_future_blinds_nobody(rig: Rig) -> None:
    pub = rig.publisher("a")

    def future(k: int, now: float) -> None:
        pub.put(encode_detection_batch(DetectionBatch("a", 10**6 + k, now + 1e6, "world", ())))

    started = time.time()
    stopped, sent = _attack(rig, 3.0, future, 0.1)
    assert rig.person_tracked_since(started + 1.0)  # tracked during the attack, too
    _still_tracked(rig, stopped)
    wait_for(lambda: rig.counter("bad_stamp") >= _most_of(sent), 5, "bad_stamp counted")


def test_a_batch_on_another_sensors_key_is_refused(rig: Rig) -> None:
    pub = rig.publisher("b")

    def impostor(k: int, now: float) -> None:  # claims to be 'a' on b's key, a ghost
        batch = DetectionBatch("a", 5000 + k, now, "world", (_det(1.0, 1.0),))
        pub.put(encode_detection_batch(batch))

    stopped, sent = _attack(rig, 2.0, impostor, 1 / 30)
    _still_tracked(rig, stopped)
    wait_for(lambda: rig.counter("sensor_mismatch") >= _most_of(sent), 5, "mismatches counted")


def test_an_uncalibrated_sensor_never_takes_the_frame(rig: Rig) -> None:
    pub = rig.publisher("cam")

    def own_frame(k: int, now: float) -> None:
        pub.put(encode_detection_batch(DetectionBatch("cam", k, now, "cam", (_det(2, 2),))))

    stopped, sent = _attack(rig, 2.0, own_frame, 1 / 30)
    _still_tracked(rig, stopped)
    wait_for(lambda: rig.counter("wrong_frame") >= _most_of(sent), 5, "wrong_frame counted")
    with rig.lock:
        assert {b.frame_id for _, b in rig.tracks} == {"world"}


def test_thousands_of_detections_per_batch_are_capped(rig: Rig) -> None:
    """Two floods of 2,000-detection batches: capped, and memory comes back after each.

    (With Zenoh's shared memory on, the first flood left 15 MiB for good: its watchdog
    threads and buffers. Sessions have it off unless a network asks for it.)
    """
    pub = rig.publisher("b")
    baseline = rig.rss_mib()

    def crowd(k: int, now: float) -> None:
        dets = tuple(_det(0.01 * (i % 100) + 0.3 * (k % 7), 0.01 * i, 0.9) for i in range(2000))
        pub.put(encode_detection_batch(DetectionBatch("b", k, now, "world", dets)))

    for flood in range(2):
        stopped, _ = _attack(rig, 5.0, crowd, 1 / 30)
        _still_tracked(rig, stopped)
        # the ghosts die, and the node gives memory back (every 10 s)
        wait_for(lambda: rig.rss_mib() < baseline * 1.10, 15,
                 f"memory within 10 % of {baseline:.1f} MiB after flood {flood + 1}")  # fmt: skip
    assert rig.counter("detections_capped") > 2 * 100_000


def test_a_flood_of_batches_on_one_key_is_rate_limited(rig: Rig) -> None:
    pub = rig.publisher("b")

    def flood(k: int, now: float) -> None:
        pub.put(encode_detection_batch(DetectionBatch("b", k, now, "world", (_det(7, 5),))))

    stopped, _ = _attack(rig, 2.0, flood, 0.0)  # as fast as this process can publish
    _still_tracked(rig, stopped)
    wait_for(lambda: rig.counter("rate_limited") > 500, 5, "rate_limited counted")


def test_thousands_of_unknown_sensors_are_ignored(rig: Rig) -> None:
    pubs = [rig.publisher(f"x{i}") for i in range(200)]
    baseline = rig.rss_mib()

    def strangers(k: int, now: float) -> None:
        sensor = f"x{k % 200}"
        batch = DetectionBatch(sensor, k, now, "world", (_det(6, 1),))
        pubs[k % 200].put(encode_detection_batch(batch))  # type: ignore[attr-defined]

    stopped, _ = _attack(rig, 3.0, strangers, 0.0005)
    _still_tracked(rig, stopped)
    wait_for(lambda: rig.counter("unknown_sensor") > 1000, 5, "unknown_sensor counted")
    assert rig.rss_mib() < baseline * 1.10, (baseline, rig.rss_mib())
