"""Zone events over real UDP: enter, leave and counts, as JSON and as OSC."""

from __future__ import annotations

import json
import socket

import pytest

from openptrack_py.config import NetworkConfig, ZoneConfig, ZoneSinkConfig
from openptrack_py.errors import ConfigError
from openptrack_py.messages import Track, TrackBatch
from openptrack_py.output.zone_events import ZoneEventSink

STAGE = ZoneConfig(name="stage", polygon=[(1.0, -1.0), (3.0, -1.0), (3.0, 1.0), (1.0, 1.0)])
BAR = ZoneConfig(name="bar", polygon=[(5.0, -1.0), (6.0, -1.0), (6.0, 1.0), (5.0, 1.0)])
T0 = 1_764_000_000.5


def _frame(t: float, *people: tuple[int, float, str | None]) -> TrackBatch:
    tracks = tuple(
        Track(id=pid, x=x, y=0.0, z=0.9, height=1.7, vx=0.0, vy=0.0, age=1.0, confidence=0.9,
              visibility=1, stable_id=None if name is None else 10000 + pid, identity=name)
        for pid, x, name in people
    )  # fmt: skip
    return TrackBatch(t, 0, "world", tracks, tuple(p[0] for p in people), 9)


@pytest.fixture
def receiver() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(2.0)
    yield sock
    sock.close()


def _received(sock: socket.socket) -> list[bytes]:
    out = []
    sock.settimeout(0.2)
    try:
        while True:
            out.append(sock.recv(65536))
    except TimeoutError:
        return out


def test_json_events_say_who_entered_and_left_which_zone(receiver: socket.socket) -> None:
    cfg = ZoneSinkConfig(port=receiver.getsockname()[1], counts_every_s=0.0)
    sink = ZoneEventSink(cfg, [STAGE, BAR])
    sink.send(_frame(T0, (4, 0.0, "Ada"), (5, 5.5, None)), 0.0)  # Ada outside, 5 at the bar
    sink.send(_frame(T0 + 1, (4, 2.0, "Ada"), (5, 5.5, None)), 1.0)  # Ada on stage
    sink.send(_frame(T0 + 2, (5, 5.5, None)), 2.0)  # Ada unseen 1 s: still on stage
    sink.send(_frame(T0 + 3.5, (5, 5.5, None)), 3.5)  # gone for good
    sink.close()
    messages = [json.loads(d) for d in _received(receiver)]
    events = [m["zone_event"] for m in messages if "zone_event" in m]
    counts = [m["zone_counts"]["zones"] for m in messages if "zone_counts" in m]
    assert [(e["zone"], e["event"], e["id"], e["name"], e["count"]) for e in events] == [
        ("bar", "enter", 5, "", 1),
        ("stage", "enter", 10004, "Ada", 1),
        ("stage", "leave", 10004, "Ada", 0),
    ]
    assert counts == [{"stage": 0, "bar": 1}, {"stage": 1, "bar": 1}, {"stage": 0, "bar": 1}]
    assert events[1]["stamp"] == {"sec": 1764000001, "nsec": 500000000}
    seqs = [m[next(iter(m))]["seq"] for m in messages]
    assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)


def test_counts_go_out_periodically_while_nothing_changes(receiver: socket.socket) -> None:
    sink = ZoneEventSink(ZoneSinkConfig(port=receiver.getsockname()[1]), [STAGE])
    sink.send(_frame(T0, (1, 2.0, None)), 100.0)
    sink.poll(100.5)  # not due
    sink.poll(101.0)
    sink.poll(102.0)
    sink.close()
    messages = [json.loads(d) for d in _received(receiver)]
    assert [m["zone_counts"]["zones"] for m in messages if "zone_counts" in m] == [
        {"stage": 1}
    ] * 3


def test_osc_messages_for_max_and_touchdesigner(receiver: socket.socket) -> None:
    pytest.importorskip("pythonosc")
    from pythonosc.osc_message import OscMessage

    cfg = ZoneSinkConfig(port=receiver.getsockname()[1], format="osc", counts_every_s=0.0)
    sink = ZoneEventSink(cfg, [STAGE])
    sink.send(_frame(T0, (4, 2.0, "Ada")), 0.0)
    sink.send(_frame(T0 + 2, (7, 0.0, None)), 2.0)
    sink.close()
    got = [OscMessage(d) for d in _received(receiver)]
    assert [(m.address, m.params) for m in got] == [
        ("/opt/zone/enter", ["stage", 10004, "Ada", 1]),
        ("/opt/zone/count", ["stage", 1]),
        ("/opt/zone/leave", ["stage", 10004, "Ada", 0]),
        ("/opt/zone/count", ["stage", 0]),
    ]


def test_a_zones_sink_needs_zones_in_the_network() -> None:
    with pytest.raises(ConfigError, match="the network file has no 'zones'"):
        ZoneEventSink(ZoneSinkConfig(), [])
    network = NetworkConfig(zones=[STAGE], outputs=[{"zones": [{"port": 9000}]}])
    assert network.outputs[0].zones[0].format == "json"
