"""Identity across restarts: a tracker killed or stopped mid-run comes back with its people.

Real processes over Zenoh: the launcher's supervisor runs the tracker node with a
checkpoint directory; this test's own session plays a sensor that sees two people
walking circles, and reads the tracks. The tracker is killed (``kill -9``), then stopped
with a stray SIGTERM; each time the supervisor restarts it, and each person must get
their own id back, and no id may go to anyone else.
"""

from __future__ import annotations

import math
import os
import signal
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from openptrack_py.config import ZenohConfig
from openptrack_py.launch import NodeSpec, Supervisor
from openptrack_py.messages import (
    Detection,
    DetectionBatch,
    TrackBatch,
    decode_track_batch,
    encode_detection_batch,
)
from openptrack_py.transport import wait_for_subscribers
from openptrack_py.transport.zenoh_bus import ZenohBus
from tests.conftest import ROOT, free_port, wait_for

pytestmark = [pytest.mark.zenoh, pytest.mark.slow]

CENTRES = ((2.0, 2.0), (6.0, 2.0))
"""Two people, each walking a 1 m circle around one of these, 4 m apart."""


def person_at(i: int, t: float) -> tuple[float, float]:
    cx, cy = CENTRES[i]
    a = t * math.pi / 4 + i
    return cx + math.cos(a), cy + math.sin(a)


@dataclass
class World:
    bus: ZenohBus
    tracks: list[tuple[float, TrackBatch]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)
    stop: threading.Event = field(default_factory=threading.Event)
    reverse: bool = False  # the sensor lists the people in the other order

    def on_tracks(self, sample: object) -> None:
        with self.lock:
            self.tracks.append((time.time(), decode_track_batch(sample.payload)))  # type: ignore[attr-defined]

    def sense(self) -> None:
        pub = self.bus.publisher("opt/default/detections/a")
        k = 0
        while not self.stop.is_set():
            now = time.time()
            order = range(len(CENTRES))
            dets = tuple(
                Detection(x=x, y=y, z=0.9, height=1.7, confidence=0.9, distance=4.0)
                for x, y in (
                    person_at(i, now) for i in (reversed(order) if self.reverse else order)
                )
            )
            pub.put(encode_detection_batch(DetectionBatch("a", k, now, "world", dets)))
            k += 1
            time.sleep(1 / 30)

    def ids_of_people(self, since: float) -> list[set[int]]:
        """The confirmed ids seen on each person since ``since``."""
        out: list[set[int]] = [set() for _ in CENTRES]
        with self.lock:
            batches = [b for t, b in self.tracks if t >= since]
        for batch in batches:
            for tr in batch.tracks:
                for i in range(len(CENTRES)):
                    x, y = person_at(i, batch.stamp)
                    if tr.confirmed and math.hypot(tr.x - x, tr.y - y) < 0.5:
                        out[i].add(tr.id)
        return out


@pytest.fixture
def world(tmp_path: Path) -> Iterator[tuple[World, Supervisor, threading.Thread]]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    net = tmp_path / "net.yaml"
    net.write_text(
        "site: default\nzenoh: {hub: null}\n"
        "sensors:\n  - {id: a, source: camera, pose: {x: 0.0, y: 0.0}}\n"
        f"tracker: {{reorder_window_s: 0.0, state_dir: {tmp_path / 'state'}, "
        "checkpoint_interval_s: 0.5}\n"
    )
    spec = NodeSpec(
        "tracker",
        "openptrack_py.nodes.tracker",
        ("-c", str(net), "-l", endpoint, "--no-multicast-scouting"),
    )
    log = (tmp_path / "launch.log").open("w")
    sup = Supervisor([spec], out=log, backoff_s=(0.2, 0.4), env={"PYTHONPATH": str(ROOT)})
    runner = threading.Thread(target=sup.run, kwargs={"duration_s": 120.0}, daemon=True)
    runner.start()
    bus = ZenohBus(ZenohConfig(hub=None, connect=[endpoint], listen=[], multicast_scouting=False))
    w = World(bus)
    bus.subscribe("opt/default/tracks", w.on_tracks)
    sensor = threading.Thread(target=w.sense, daemon=True)
    try:
        assert wait_for_subscribers(bus.publisher("opt/default/detections/a"), timeout_s=30)
        sensor.start()
        yield w, sup, sensor
    finally:
        w.stop.set()
        sensor.join(5)
        bus.close()
        sup.request_stop()
        runner.join(30)
        log.close()


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["kill-9", "sigterm"])
def test_the_same_people_keep_their_ids_across_a_tracker_restart(
    world: tuple[World, Supervisor, threading.Thread], sig: signal.Signals
) -> None:
    w, sup, _ = world
    wait_for(lambda: all(len(s) == 1 for s in w.ids_of_people(0.0)), 20, "both people tracked")
    time.sleep(1.5)  # a checkpoint or two
    before = w.ids_of_people(0.0)
    assert all(len(s) == 1 for s in before), before
    pid = sup.pids()["tracker"]
    w.reverse = True  # a tracker starting afresh would now number them the other way round
    os.kill(pid, sig)
    killed = time.time()
    wait_for(lambda: sup.pids().get("tracker", pid) != pid, 20, "the restart")
    wait_for(lambda: all(w.ids_of_people(killed + 0.1)), 30, "tracks after the restart")
    time.sleep(2.0)
    after = w.ids_of_people(killed + 0.1)
    assert after == before, (before, after)  # each person their own id back, nobody else's
    with w.lock:
        later = [b for t, b in w.tracks if t > killed]
    published = {tr.id for b in later for tr in b.tracks}
    assert published <= set().union(*before), published  # no id went to someone else
