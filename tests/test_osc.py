"""OSC bundles: golden bytes, and what python-osc reads back from them.

The golden files ``tests/golden/osc_*.bin`` hold the exact datagrams ``build_bundle`` made
for the frames below. They were written once and are compared byte-for-byte: a change to
what Max, TouchDesigner or Processing patches receive must be deliberate (new golden
files), never a side effect.
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from openptrack_py.messages import Track, TrackBatch, Visibility
from openptrack_py.output.osc import build_bundle

OscBundle = pytest.importorskip("pythonosc.osc_bundle").OscBundle
IMMEDIATELY = pytest.importorskip("pythonosc.osc_bundle_builder").IMMEDIATELY

GOLDEN = Path(__file__).parent / "golden"
STAMP = 1441244414.25  # exactly representable: nsec = 250000000

TRACKS = (
    Track(id=170, x=0.740519, y=-3.21577, z=0.9, height=1.01898, vx=0.1, vy=0.0,
          age=79.4518, confidence=0.491777),
    Track(id=171, x=12.5, y=-0.0, z=0.8, height=1.7, vx=0.0, vy=0.0, age=0.0333333,
          confidence=1.0, visibility=Visibility.NOT_VISIBLE),
    Track(id=200, x=1234567.0, y=1.23e-05, z=1.0, height=1.83, vx=0.0, vy=0.0, age=3600.0,
          confidence=0.5, stable_id=4, identity="alice"),
)  # fmt: skip
FRAME = TrackBatch(STAMP, 7, "world", TRACKS, (170, 171, 200, 201), 201)
EMPTY = TrackBatch(STAMP, 8, "world", (), (), 201)

CASES = {
    "osc_tracks": lambda: build_bundle(FRAME, 123),  # the sink's own seq, not the frame's
    "osc_empty_prefix": lambda: build_bundle(EMPTY, 124, prefix="/room2"),
}


def _f32(value: float) -> float:
    return struct.unpack(">f", struct.pack(">f", value))[0]


@pytest.mark.parametrize("name", list(CASES), ids=list(CASES))
def test_golden_bytes(name: str) -> None:
    assert CASES[name]() == (GOLDEN / f"{name}.bin").read_bytes()


def _read(name: str) -> tuple[object, list[tuple[str, list]]]:
    bundle = OscBundle((GOLDEN / f"{name}.bin").read_bytes())
    return bundle, [(m.address, list(m.params)) for m in bundle]


def test_the_golden_bundle_reads_back_as_documented() -> None:
    data = (GOLDEN / "osc_tracks.bin").read_bytes()
    assert data[:16] == b"#bundle\x00" + b"\x00" * 7 + b"\x01"  # OSC time tag "immediately"
    bundle, messages = _read("osc_tracks")
    assert bundle.timestamp == IMMEDIATELY
    assert messages == [
        ("/opt/frame", [123, 1441244414, 250_000_000, 3, 201]),
        *(
            ("/opt/track", [t.id, *map(_f32, (t.x, t.y, t.height, t.age, t.confidence))])
            for t in TRACKS
        ),
        ("/opt/identity", [200, 4, "alice"]),  # only tracks with a stable identity
        ("/opt/alive", [170, 171, 200, 201]),
    ]
    types = [[type(p) for p in params] for _, params in messages]
    assert types == [[int] * 5, *[[int] + [float] * 5] * 3, [int, int, str], [int] * 4]
    assert str(messages[2][1][2]) == "-0.0"  # negative zero survives


def test_an_empty_frame_has_a_frame_and_an_alive_message_without_arguments() -> None:
    bundle, messages = _read("osc_empty_prefix")
    assert bundle.timestamp == IMMEDIATELY
    assert messages == [
        ("/room2/frame", [124, 1441244414, 250_000_000, 0, 201]),
        ("/room2/alive", []),
    ]
