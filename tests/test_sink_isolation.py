"""Sinks are isolated: a slow or dead receiver never stalls the others or the tracker."""

from __future__ import annotations

import itertools
import math
import socket
import threading
import time
from collections.abc import Callable, Iterator
from statistics import median

import pytest

from openptrack_py.config import (
    NetworkConfig,
    OscSinkConfig,
    OutputConfig,
    SmootherConfig,
    UdpSinkConfig,
    WebConfig,
)
from openptrack_py.messages.codec import decode_track_batch, encode_track_batch
from openptrack_py.messages.track import Track, TrackBatch, Visibility
from openptrack_py.output.opt_json import parse_datagram
from openptrack_py.output.service import OutputService
from openptrack_py.output.sinks import SinkWorker, UdpJsonSink
from openptrack_py.runtime.counters import Counters
from openptrack_py.runtime.node import Node
from openptrack_py.transport import MemoryBus
from tests.conftest import wait_for

UNRESOLVABLE = "no-such-host.invalid"  # RFC 6761: never resolves
TEST_NET = "198.51.100.7"  # RFC 5737 TEST-NET-2: routed nowhere on the Internet


def _track(
    ident: int, x: float, y: float, visibility: Visibility = Visibility.VISIBLE, **kw: float
) -> Track:
    fields = {"z": 0.9, "height": 1.7, "vx": 0.0, "vy": 0.0, "age": 1.0, "confidence": 0.9}
    return Track(ident, x, y, **{**fields, **kw}, visibility=visibility)


def _frame(seq: int, *tracks: Track, alive: tuple[int, ...] | None = None) -> TrackBatch:
    ids = tuple(t.id for t in tracks) if alive is None else alive
    return TrackBatch(1_700_000_000.0 + seq / 30, seq, "world", tracks, ids, max(ids, default=0))


def _dead_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Receiver:
    """A live UDP socket on loopback that keeps every datagram."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.datagrams: list[bytes] = []
        self.cond = threading.Condition()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.sock.recv(1 << 16)
            except TimeoutError:
                continue
            except OSError:
                return
            with self.cond:
                self.datagrams.append(data)
                self.cond.notify_all()

    def wait(self, predicate: Callable[[list[bytes]], object], timeout: float = 10.0) -> bool:
        with self.cond:
            return bool(self.cond.wait_for(lambda: predicate(self.datagrams), timeout))

    def parsed(self) -> list[dict]:
        with self.cond:
            return [parse_datagram(d) for d in self.datagrams]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self.sock.close()


@pytest.fixture
def receiver() -> Iterator[Receiver]:
    r = Receiver()
    yield r
    r.close()


def _tracks_messages(msgs: list[dict]) -> list[dict]:
    return [m for m in msgs if "people_tracks" in m or "tracks" in m]


def _heartbeats(msgs: list[dict]) -> list[dict]:
    return [m for m in msgs if "alive_IDs" in m]


# ====================================================================== SinkWorker


class BlockingSink:
    """A sink whose first send blocks until released; records everything it gets."""

    poll_interval_s = None

    def __init__(self, name: str = "stuck") -> None:
        self.name = name
        self.entered = threading.Event()
        self.release = threading.Event()
        self.received: list[int] = []
        self.closed = False

    def send(self, frame: TrackBatch, now: float) -> None:
        self.entered.set()
        assert self.release.wait(30), "never released"
        self.received.append(frame.seq)

    def poll(self, now: float) -> None:
        pass

    def close(self) -> None:
        self.closed = True


class RecordingSink:
    """A fast sink that records every frame and lets the test wait for one."""

    poll_interval_s = None

    def __init__(self, name: str) -> None:
        self.name = name
        self.received: list[int] = []
        self.cond = threading.Condition()
        self.closed = False

    def send(self, frame: TrackBatch, now: float) -> None:
        with self.cond:
            self.received.append(frame.seq)
            self.cond.notify_all()

    def poll(self, now: float) -> None:
        pass

    def close(self) -> None:
        self.closed = True

    def wait_for_seq(self, seq: int, timeout: float = 10.0) -> bool:
        with self.cond:
            return self.cond.wait_for(lambda: seq in self.received, timeout)


def test_a_blocked_sink_never_blocks_the_producer_nor_the_other_sinks() -> None:
    counters = Counters("output")
    stuck = BlockingSink()
    fast = [RecordingSink("a"), RecordingSink("b")]
    workers = [SinkWorker(stuck, counters, queue_size=4)]
    workers += [SinkWorker(s, counters, queue_size=4) for s in fast]
    try:
        workers[0].submit(_frame(0))
        assert stuck.entered.wait(10)  # the stuck sink now holds frame 0 and waits
        for seq in range(1, 1001):
            frame = _frame(seq, _track(1, 0.01 * seq, 2.0))
            for w in workers:
                w.submit(frame)  # must return at once, whatever the stuck sink does
            # the others keep pace, frame by frame, while the stuck sink is still stuck
            for s in fast:
                assert s.wait_for_seq(seq), f"sink {s.name} stalled at frame {seq}"
        # 1000 submissions returned while the stuck sink was still inside its first send
        assert not stuck.release.is_set() and stuck.received == []
        assert workers[0]._thread.is_alive()
        for s in fast:
            assert s.received == list(range(1, 1001))  # every frame, in order
        assert counters.get("a.dropped") == counters.get("b.dropped") == 0
        # the stuck one kept only the newest 4 and counted the rest as dropped
        assert counters.get("stuck.dropped") == 1000 - 4
        assert len(workers[0]._queue) == 4
        stuck.release.set()
    finally:
        stuck.release.set()
        for w in workers:
            w.close()
    assert stuck.received == [0, 997, 998, 999, 1000]  # oldest dropped first, the rest sent
    assert counters.get("stuck.sent") == 5 and counters.get("a.sent") == 1000
    assert all(not w._thread.is_alive() for w in workers)
    assert stuck.closed and all(s.closed for s in fast)


def test_close_does_not_hang_on_a_stuck_sink_and_still_closes_it() -> None:
    stuck = BlockingSink()
    worker = SinkWorker(stuck, Counters("output"))
    worker.submit(_frame(1))
    assert stuck.entered.wait(10)
    worker.close(timeout_s=0.2)  # returns although the send never finishes
    stuck.release.set()
    worker._thread.join(10)
    assert not worker._thread.is_alive()
    assert stuck.closed


class RecordingBlockingSink(BlockingSink):
    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.used_after_close: list[int] = []

    def send(self, frame: TrackBatch, now: float) -> None:
        if self.closed:
            self.used_after_close.append(frame.seq)
        super().send(frame, now)


def test_a_sink_is_not_used_after_it_was_closed() -> None:
    sink = RecordingBlockingSink("s")
    worker = SinkWorker(sink, Counters("output"), queue_size=4)
    worker.submit(_frame(1))
    assert sink.entered.wait(10)
    worker.submit(_frame(2))
    worker.submit(_frame(3))
    worker.close(timeout_s=0.1)  # gives up on the stuck send
    sink.release.set()
    worker._thread.join(10)
    assert not worker._thread.is_alive()
    assert sink.used_after_close == []


def test_close_sends_what_is_queued_first() -> None:
    sink = BlockingSink("s")
    worker = SinkWorker(sink, Counters("output"), queue_size=8)
    worker.submit(_frame(1))
    assert sink.entered.wait(10)
    for seq in (2, 3, 4):
        worker.submit(_frame(seq))
    sink.release.set()
    worker.close(timeout_s=10)
    assert sink.received == [1, 2, 3, 4] and sink.closed


def test_a_sink_that_raises_is_counted_and_goes_on() -> None:
    class Flaky(RecordingSink):
        def send(self, frame: TrackBatch, now: float) -> None:
            if frame.seq % 2:
                raise ValueError("odd frame") if frame.seq % 4 == 1 else OSError("no route")
            super().send(frame, now)

    counters = Counters("output")
    sink = Flaky("flaky")
    worker = SinkWorker(sink, counters, queue_size=100)
    try:
        for seq in range(1, 11):
            worker.submit(_frame(seq))
        assert sink.wait_for_seq(10)
    finally:
        worker.close()
    assert sink.received == [2, 4, 6, 8, 10]
    assert counters.get("flaky.errors") == 5 and counters.get("flaky.sent") == 5


# ===================================================================== UdpJsonSink


def test_dead_udp_destinations_count_errors_and_never_stall_a_live_one(
    receiver: Receiver,
) -> None:
    counters = Counters("output")
    hb = 0.05
    cfgs = {
        # heartbeats every 0.25 s: each is one more DNS query
        "unresolvable": UdpSinkConfig(host=UNRESOLVABLE, port=21234),
        "nobody": UdpSinkConfig(host="127.0.0.1", port=_dead_udp_port(), heartbeat_interval_s=hb),
        "testnet": UdpSinkConfig(host=TEST_NET, port=21234, heartbeat_interval_s=hb),
        "live": UdpSinkConfig(host="127.0.0.1", port=receiver.port, heartbeat_interval_s=hb),
    }
    workers = {name: SinkWorker(UdpJsonSink(c, name), counters) for name, c in cfgs.items()}
    n = 60
    try:
        for seq in range(1, n + 1):
            frame = _frame(seq, _track(3, 1.0 + 0.01 * seq, 2.5))
            for w in workers.values():
                w.submit(frame)  # never raises, never waits
            # paced by the live receiver, so the live sink's queue never overflows
            assert receiver.wait(lambda d, k=seq: len(_tracks_messages(_parse(d))) >= k), seq
        # the room empties: heartbeats go on, with no alive ids, and no tracks messages
        empty = _frame(n + 1, alive=())
        for w in workers.values():
            w.submit(empty)
        base = len(_heartbeats(receiver.parsed()))
        assert receiver.wait(lambda d: len(_heartbeats(_parse(d))) >= base + 5)
        # a resolver may take seconds to say no (some throttle bursts of queries): only
        # that sink's thread waits
        wait_for(lambda: counters.get("unresolvable.errors") > 0, 30, "a failed lookup")
        assert all(w._thread.is_alive() for w in workers.values())
    finally:
        for w in workers.values():
            w.close()
    msgs = receiver.parsed()
    tracks = _tracks_messages(msgs)
    assert [m["header"]["seq"] for m in tracks] == list(range(1, n + 2))  # every frame
    assert [m["people_tracks"][0]["x"] for m in tracks[:n]] == [
        pytest.approx(1.0 + 0.01 * s) for s in range(1, n + 1)
    ]
    assert tracks[-1]["people_tracks"] == []
    beats = _heartbeats(msgs)
    assert [b["header"]["seq"] for b in beats] == list(range(1, len(beats) + 1))
    assert beats[-1]["alive_IDs"] == [] and beats[-1]["max_ID"] == 0
    assert all(b["header"]["frame_id"] == "heartbeat" for b in beats)
    assert counters.get("live.sent") == n + 1 and counters.get("live.errors") == 0
    assert counters.get("live.dropped") == 0
    # unresolvable: every frame fails and is counted on the sink's own thread, or is dropped
    # while that thread waits for the resolver (all but the queue and the one in hand when
    # close() stopped waiting for it)
    assert counters.get("unresolvable.sent") == 0
    unresolved = counters.get("unresolvable.errors") + counters.get("unresolvable.dropped")
    assert counters.get("unresolvable.errors") > 0 and unresolved >= n + 1 - 5
    # the others: sendto() may succeed (UDP does not know) or fail (no route); either way
    # each frame is accounted for and nothing reached the producer
    for name in ("nobody", "testnet"):
        done = counters.get(f"{name}.sent") + counters.get(f"{name}.dropped")
        assert done + counters.get(f"{name}.errors") >= n + 1, name
    for name in ("live", "nobody", "testnet"):  # (the other may still wait for its resolver)
        assert not workers[name]._thread.is_alive() and workers[name].sink._sock.fileno() == -1


def _parse(datagrams: list[bytes]) -> list[dict]:
    return [parse_datagram(d) for d in datagrams]


def test_a_frame_that_cannot_be_encoded_is_an_error_and_the_next_goes_out(
    receiver: Receiver,
) -> None:
    counters = Counters("output")
    cfg = UdpSinkConfig(host="127.0.0.1", port=receiver.port, heartbeat=False)
    worker = SinkWorker(UdpJsonSink(cfg, "udp0"), counters)
    try:
        worker.submit(_frame(1, _track(1, math.nan, 1.0)))  # never NaN on the wire
        worker.submit(_frame(2, _track(1, 1.0, 1.0)))
        assert receiver.wait(lambda d: len(d) >= 1)
    finally:
        worker.close()
    assert counters.get("udp0.errors") == 1 and counters.get("udp0.sent") == 1
    (only,) = receiver.parsed()
    assert only["people_tracks"][0]["x"] == 1.0


def test_heartbeats_go_on_while_the_room_is_empty(receiver: Receiver) -> None:
    cfg = UdpSinkConfig(host="127.0.0.1", port=receiver.port, heartbeat_interval_s=0.02)
    worker = SinkWorker(UdpJsonSink(cfg, "udp0"), Counters("output"))
    try:  # no frame at all
        assert receiver.wait(lambda d: len(d) >= 5)
    finally:
        worker.close()
    msgs = receiver.parsed()
    assert msgs and all(m["alive_IDs"] == [] and m["max_ID"] == 0 for m in msgs)
    assert receiver.datagrams[0].endswith(b"}\x00")  # OpenPTrack's trailing NUL
    stamps = [m["header"]["stamp"]["sec"] + m["header"]["stamp"]["nsec"] / 1e9 for m in msgs]
    assert stamps == sorted(stamps)


def test_a_frame_dropped_before_the_sink_shows_as_a_gap_in_seq(receiver: Receiver) -> None:
    """The sink sends each frame's own number: a client can tell that frame 3 was lost."""
    cfg = UdpSinkConfig(host="127.0.0.1", port=receiver.port, heartbeat=False)
    sink = UdpJsonSink(cfg, "udp0")
    try:
        for seq in (1, 2, 4, 5):  # 3 was dropped by a full queue
            sink.send(_frame(seq, _track(7, 1.0, 1.0)), 0.0)
        assert receiver.wait(lambda d: len(d) >= 4)
    finally:
        sink.close()
    assert [m["header"]["seq"] for m in receiver.parsed()] == [1, 2, 4, 5]


# ================================================================ OutputService


def _osc_messages(datagrams: list[bytes]) -> list[list[tuple[str, list]]]:
    from pythonosc.osc_bundle import OscBundle

    return [[(m.address, list(m.params)) for m in OscBundle(d)] for d in datagrams]


def test_output_service_end_to_end_on_a_memory_bus() -> None:
    pytest.importorskip("pythonosc")
    live, osc = Receiver(), Receiver()
    rate = 30.0
    cfg = OutputConfig(
        smoother=SmootherConfig(rate_hz=rate),
        udp=[  # a dead destination without DNS (the test above has the unresolvable one)
            UdpSinkConfig(host=TEST_NET, port=21234),
            UdpSinkConfig(host="127.0.0.1", port=live.port),
        ],
        osc=[OscSinkConfig(host="127.0.0.1", port=osc.port)],
        web=WebConfig(port=0),
    )
    bus = MemoryBus()
    node = Node("output", bus, stats_interval_s=0)
    node.start()
    smoothed: list[TrackBatch] = []
    bus.subscribe(
        "opt/default/tracks/smoothed", lambda s: smoothed.append(decode_track_batch(s.payload))
    )
    service = OutputService(node, cfg, NetworkConfig())
    runner = threading.Thread(target=service.run, daemon=True)
    runner.start()
    pub = bus.publisher("opt/default/tracks")
    try:
        for seq in range(1, 31):  # one second of a person standing at (2, 3)
            pub.put(encode_track_batch(_frame(seq, _track(7, 2.0, 3.0))))
            time.sleep(1 / 30)

        def with_track(datagrams: list[bytes]) -> int:
            return sum(1 for m in _tracks_messages(_parse(datagrams)) if m["people_tracks"])

        assert live.wait(lambda d: with_track(d) >= 10), live.parsed()[-3:]
        assert osc.wait(lambda d: len(d) >= 20)
    finally:
        node.stop()
        runner.join(15)
        node.close()
        bus.close()
        live.close()
        osc.close()
    assert not runner.is_alive()

    # the live UDP sink: a frame per smoother tick, the person where it stood
    tracks = _tracks_messages(live.parsed())
    seen = [m for m in tracks if m["people_tracks"]]
    assert all(m["people_tracks"] == [seen[0]["people_tracks"][0]] for m in seen)
    person = seen[0]["people_tracks"][0]
    assert (person["id"], person["x"], person["y"]) == (7, 2.0, 3.0)
    assert [m["header"]["seq"] for m in tracks] == list(range(1, len(tracks) + 1))
    stamps = [m["header"]["stamp"]["sec"] + m["header"]["stamp"]["nsec"] / 1e9 for m in tracks]
    gaps = [b - a for a, b in itertools.pairwise(stamps)]
    assert all(g > 0 for g in gaps)
    # at the smoother's rate: never faster (drift-free ticks), typically on time
    assert len(tracks) <= (stamps[-1] - stamps[0]) * rate + 2
    assert median(gaps) == pytest.approx(1 / rate, rel=0.5)

    # the OSC sink got the same frames as bundles
    bundles = _osc_messages(osc.datagrams)
    frames = [args for b in bundles for addr, args in b if addr == "/opt/frame"]
    assert [f[0] for f in frames] == list(range(1, len(frames) + 1))
    people = [args for b in bundles for addr, args in b if addr == "/opt/track"]
    assert people and all(p[0] == 7 for p in people)
    assert people[0][1] == pytest.approx(2.0) and people[0][2] == pytest.approx(3.0)
    assert abs(len(frames) - len(tracks)) <= 3

    # the dead destination took every frame (UDP cannot tell), nothing else was disturbed
    c = node.counters
    assert c.get("udp0.sent") + c.get("udp0.errors") + c.get("udp0.dropped") == c.get("frames")
    assert c.get("udp1.errors") == 0 and c.get("osc0.errors") == 0
    assert c.get("frames") >= len(tracks)
    assert len(smoothed) == c.get("frames")  # republished on opt/default/tracks/smoothed
    assert c.get("in") == 30 and c.get("malformed") == 0

    # stopped: every worker thread ended, every socket closed, the web server gone
    assert all(not w._thread.is_alive() for w in service.workers)
    assert all(w.sink._sock.fileno() == -1 for w in service.workers if hasattr(w.sink, "_sock"))
    assert service.web is not None and not service.web._thread.is_alive()
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection(("127.0.0.1", service.web.port), timeout=5).close()
