"""Tests for openptrack_py.messages: wire codecs, golden bytes, strict decoding, key routing.

The golden files under ``tests/golden/`` hold the exact bytes the encoders produced for the
hand-built messages in ``GOLDEN`` below. They were written once and are compared
byte-for-byte: a change to the wire format must be deliberate (new schema version, new
golden files), never a side effect.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import orjson
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from openptrack_py.errors import WireFormatError
from openptrack_py.messages import (
    SCHEMA_VERSION,
    ConfigAck,
    ConfigUpdate,
    Detection,
    DetectionBatch,
    GroundTruthFrame,
    Heartbeat,
    NodeStats,
    PersonState,
    Track,
    TrackBatch,
    Visibility,
    control_codec,
    data_codec,
    decode_config_ack,
    decode_config_update,
    decode_detection_batch,
    decode_ground_truth,
    decode_heartbeat,
    decode_node_stats,
    decode_track_batch,
    encode_config_ack,
    encode_config_update,
    encode_detection_batch,
    encode_ground_truth,
    encode_heartbeat,
    encode_node_stats,
    encode_track_batch,
)
from openptrack_py.messages.by_key import TOPICS, decoder_for_key
from openptrack_py.messages.codec import (
    MAX_APPEARANCE_BINS,
    MAX_FACE_DIMS,
    MAX_ITEMS,
    MAX_NAME_LEN,
    MAX_PAYLOAD_BYTES,
)

GOLDEN_DIR = Path(__file__).parent / "golden"
MAX_ID = (1 << 31) - 1
MAX_INT = (1 << 63) - 1

# kind on the wire -> (encoder, decoder, message type)
CODECS: dict[str, tuple[Callable[[Any], bytes], Callable[[Any], Any], type]] = {
    "detections": (encode_detection_batch, decode_detection_batch, DetectionBatch),
    "tracks": (encode_track_batch, decode_track_batch, TrackBatch),
    "heartbeat": (encode_heartbeat, decode_heartbeat, Heartbeat),
    "ground_truth": (encode_ground_truth, decode_ground_truth, GroundTruthFrame),
    "stats": (encode_node_stats, decode_node_stats, NodeStats),
    "config_update": (encode_config_update, decode_config_update, ConfigUpdate),
    "config_ack": (encode_config_ack, decode_config_ack, ConfigAck),
}
DECODERS = [dec for _, dec, _ in CODECS.values()]
DECODER_IDS = list(CODECS)


# ------------------------------------------------------------------ golden messages

GOLDEN: dict[str, Any] = {
    "detections": DetectionBatch(
        sensor_id="k2_a",
        seq=42,
        stamp=1700000000.125,
        frame_id="world",
        detections=(
            Detection(x=1.5, y=-2.25, z=0.875, height=1.75, confidence=0.9, distance=3.1),
            Detection(
                x=0.1,
                y=4.0,
                z=0.9,
                height=1.2,
                confidence=0.5,
                distance=4.2,
                bbox=(120, 40, 64, 180),
                appearance=(0, 17, 255, 3),
                face=(0.25, -0.5, 1e-3),
            ),
        ),
    ),
    "tracks": TrackBatch(
        stamp=1700000000.25,
        seq=7,
        frame_id="world",
        tracks=(
            Track(
                id=3,
                x=1.0,
                y=2.0,
                z=0.9,
                height=1.7,
                vx=0.5,
                vy=-0.25,
                age=12.5,
                confidence=0.95,
            ),
            Track(
                id=5,
                x=-1.5,
                y=0.0,
                z=0.8,
                height=1.1,
                vx=0.0,
                vy=0.0,
                age=0.5,
                confidence=0.4,
                visibility=Visibility.OCCLUDED,
                confirmed=False,
            ),
            Track(
                id=9,
                x=3.25,
                y=-4.5,
                z=1.0,
                height=1.85,
                vx=-1.25,
                vy=1.0,
                age=100.0,
                confidence=0.7,
                visibility=Visibility.NOT_VISIBLE,
                stable_id=2,
                identity="alice",
            ),
        ),
        alive_ids=(3, 5, 9, 11),
        max_id=11,
    ),
    "heartbeat": Heartbeat(stamp=1700000001.5, seq=3, alive_ids=(3, 5, 9), max_id=11),
    "ground_truth": GroundTruthFrame(
        stamp=1700000000.0,
        seq=100,
        people=(
            PersonState(id=0, x=1.0, y=2.0, height=1.8, vx=0.5, vy=0.0),
            PersonState(
                id=1, x=-3.5, y=0.25, height=1.2, vx=0.0, vy=-0.75, kind="child", covered=False
            ),
        ),
    ),
    "stats": NodeStats(
        node="tracker",
        stamp=1700000002.0,
        uptime_s=60.5,
        counters={"in": 1800, "out": 1795, "dropped": 5, "malformed": 0},
        rates_hz={"in": 30.0, "out": 29.9},
        timings_ms={"step": 1.25},
        pid=4242,
        host="master",
    ),
    "config_update": ConfigUpdate(
        id="a1b2c3",
        set={"gate_probability": 0.99, "publish_tentative": True, "late_policy": "drop"},
    ),
    "config_ack": ConfigAck(
        id="a1b2c3",
        node="tracker",
        accepted=False,
        error="gate_probability: must be <= 0.99999 (received 2)",
        config={"gate_probability": 0.95, "late_policy": "oosm"},
    ),
}
GOLDEN_FILES = {kind: GOLDEN_DIR / f"{kind}_v{SCHEMA_VERSION}.json" for kind in GOLDEN}


def _golden_dict(kind: str) -> dict:
    """A fresh, mutable copy of the golden message of ``kind`` as a JSON object.

    Built from the encoder (pinned to the golden files by the tests below) so that this
    module imports even before the golden files exist.
    """
    return orjson.loads(CODECS[kind][0](GOLDEN[kind]))


@pytest.mark.parametrize("kind", list(GOLDEN), ids=list(GOLDEN))
def test_golden_encode_is_byte_identical(kind: str) -> None:
    encode = CODECS[kind][0]
    assert encode(GOLDEN[kind]) == GOLDEN_FILES[kind].read_bytes()


@pytest.mark.parametrize("kind", list(GOLDEN), ids=list(GOLDEN))
def test_golden_decodes_to_expected(kind: str) -> None:
    _, decode, cls = CODECS[kind]
    message = decode(GOLDEN_FILES[kind].read_bytes())
    assert type(message) is cls
    assert message == GOLDEN[kind]


@pytest.mark.parametrize("kind", list(GOLDEN), ids=list(GOLDEN))
def test_golden_first_keys_are_version_then_kind(kind: str) -> None:
    raw = GOLDEN_FILES[kind].read_bytes()
    assert raw.startswith(b'{"v":%d,"kind":"%s",' % (SCHEMA_VERSION, kind.encode()))
    assert list(orjson.loads(raw))[:2] == ["v", "kind"]


def test_golden_tracks_carry_visibility_as_int_and_optional_fields_only_when_set() -> None:
    tracks = _golden_dict("tracks")["tracks"]
    assert [t["visibility"] for t in tracks] == [0, 1, 2]
    assert [t["confirmed"] for t in tracks] == [True, False, True]
    assert ["stable_id" in t or "identity" in t for t in tracks] == [False, False, True]
    dets = _golden_dict("detections")["detections"]
    assert {"bbox", "appearance", "face"}.isdisjoint(dets[0])
    assert dets[1]["bbox"] == [120, 40, 64, 180]


@pytest.mark.parametrize(
    "payload_type",
    [bytes, bytearray, memoryview, lambda b: b.decode()],
    ids=["bytes", "bytearray", "memoryview", "str"],
)
def test_decoders_accept_every_buffer_type(payload_type: Callable[[bytes], Any]) -> None:
    raw = GOLDEN_FILES["tracks"].read_bytes()
    assert decode_track_batch(payload_type(raw)) == GOLDEN["tracks"]


# ------------------------------------------------------------- round-trip properties


def _finite(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


any_finite = st.floats(allow_nan=False, allow_infinity=False)
names = st.from_regex(rf"[A-Za-z0-9_.\-]{{1,{MAX_NAME_LEN}}}", fullmatch=True)
coords = _finite(-1.0e4, 1.0e4)
heights = _finite(0.0, 10.0)
unit = _finite(0.0, 1.0)
speeds = _finite(-1.0e3, 1.0e3)
stamps = _finite(0.0, 1.0e11)
seqs = st.integers(0, MAX_INT)
track_ids = st.integers(1, MAX_ID)
id_lists = st.lists(track_ids, max_size=40).map(tuple)

detections = st.builds(
    Detection,
    x=coords,
    y=coords,
    z=coords,
    height=heights,
    confidence=unit,
    distance=_finite(0.0, 1.0e4),
    bbox=st.none()
    | st.tuples(
        st.integers(-(1 << 20), 1 << 20),
        st.integers(-(1 << 20), 1 << 20),
        st.integers(0, 1 << 20),
        st.integers(0, 1 << 20),
    ),
    appearance=st.none() | st.lists(st.integers(0, 255), max_size=MAX_APPEARANCE_BINS).map(tuple),
    face=st.none() | st.lists(any_finite, max_size=64).map(tuple),
)
detection_batches = st.builds(
    DetectionBatch,
    sensor_id=names,
    seq=seqs,
    stamp=stamps,
    frame_id=names,
    detections=st.lists(detections, max_size=8).map(tuple),
)
tracks = st.builds(
    Track,
    id=track_ids,
    x=coords,
    y=coords,
    z=coords,
    height=heights,
    vx=speeds,
    vy=speeds,
    age=_finite(0.0, 1.0e9),
    confidence=unit,
    visibility=st.sampled_from(Visibility),
    confirmed=st.booleans(),
    stable_id=st.none() | st.integers(0, MAX_ID),
    identity=st.none() | st.text(max_size=MAX_NAME_LEN),
)
track_batches = st.builds(
    TrackBatch,
    stamp=stamps,
    seq=seqs,
    frame_id=names,
    tracks=st.lists(tracks, max_size=8).map(tuple),
    alive_ids=id_lists,
    max_id=st.integers(0, MAX_ID),
)
heartbeats = st.builds(
    Heartbeat, stamp=stamps, seq=seqs, alive_ids=id_lists, max_id=st.integers(0, MAX_ID)
)
people = st.builds(
    PersonState,
    id=st.integers(0, MAX_INT),
    x=coords,
    y=coords,
    height=heights,
    vx=speeds,
    vy=speeds,
    kind=st.sampled_from(["adult", "child"]),
    covered=st.booleans(),
)
ground_truth_frames = st.builds(
    GroundTruthFrame, stamp=stamps, seq=seqs, people=st.lists(people, max_size=8).map(tuple)
)
stat_names = st.text(max_size=MAX_NAME_LEN)
node_stats = st.builds(
    NodeStats,
    node=names,
    stamp=stamps,
    uptime_s=_finite(0.0, 1.0e10),
    counters=st.dictionaries(stat_names, st.integers(-(1 << 63), MAX_INT), max_size=10),
    rates_hz=st.dictionaries(stat_names, any_finite, max_size=10),
    timings_ms=st.dictionaries(stat_names, any_finite, max_size=10),
    pid=st.integers(0, MAX_INT),
    host=st.text(max_size=255),
)
STRATEGIES = {
    "detections": detection_batches,
    "tracks": track_batches,
    "heartbeat": heartbeats,
    "ground_truth": ground_truth_frames,
    "stats": node_stats,
}


def _check_round_trip(kind: str, message: Any) -> None:
    encode, decode, cls = CODECS[kind]
    raw = encode(message)
    assert raw.startswith(b'{"v":%d,"kind":"%s",' % (SCHEMA_VERSION, kind.encode()))
    back = decode(raw)
    assert type(back) is cls
    assert back == message
    assert encode(back) == raw  # decode(encode(x)) re-encodes to identical bytes


ROUND_TRIP = settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


@ROUND_TRIP
@given(detection_batches)
def test_round_trip_detection_batch(batch: DetectionBatch) -> None:
    _check_round_trip("detections", batch)


@ROUND_TRIP
@given(track_batches)
def test_round_trip_track_batch(batch: TrackBatch) -> None:
    _check_round_trip("tracks", batch)


@ROUND_TRIP
@given(heartbeats)
def test_round_trip_heartbeat(heartbeat: Heartbeat) -> None:
    _check_round_trip("heartbeat", heartbeat)


@ROUND_TRIP
@given(ground_truth_frames)
def test_round_trip_ground_truth(frame: GroundTruthFrame) -> None:
    _check_round_trip("ground_truth", frame)


@ROUND_TRIP
@given(node_stats)
def test_round_trip_node_stats(stats: NodeStats) -> None:
    _check_round_trip("stats", stats)


@pytest.mark.parametrize(
    "kind, message",
    [
        (
            "detections",
            DetectionBatch(
                sensor_id="s" * MAX_NAME_LEN,
                seq=MAX_INT,
                stamp=1.0e11,
                frame_id="world",
                detections=(
                    Detection(
                        x=-1.0e4,
                        y=1.0e4,
                        z=0.0,
                        height=10.0,
                        confidence=1.0,
                        distance=1.0e4,
                        bbox=(-(1 << 20), 1 << 20, 0, 1 << 20),
                        appearance=tuple([255] * MAX_APPEARANCE_BINS),
                        face=tuple([1.0e300] * MAX_FACE_DIMS),
                    ),
                    *[Detection(x=0.5, y=0.5, z=1.0, height=1.7, confidence=0.5, distance=2.0)]
                    * (MAX_ITEMS - 1),
                ),
            ),
        ),
        (
            "tracks",
            TrackBatch(
                stamp=0.0,
                seq=0,
                tracks=(
                    Track(
                        id=MAX_ID,
                        x=1.0e4,
                        y=-1.0e4,
                        z=0.0,
                        height=0.0,
                        vx=1.0e3,
                        vy=-1.0e3,
                        age=1.0e9,
                        confidence=0.0,
                        stable_id=0,
                        identity="é" * MAX_NAME_LEN,
                    ),
                ),
                alive_ids=tuple(range(1, MAX_ITEMS + 1)),
                max_id=MAX_ID,
            ),
        ),
        ("heartbeat", Heartbeat(stamp=0.0, seq=MAX_INT, alive_ids=(MAX_ID,), max_id=MAX_ID)),
        ("stats", NodeStats(node="n", stamp=0.0, uptime_s=1.0e10, host="h" * 255)),
    ],
    ids=["detections-at-limits", "tracks-at-limits", "heartbeat-at-limits", "stats-at-limits"],
)
def test_round_trip_at_documented_limits(kind: str, message: Any) -> None:
    _check_round_trip(kind, message)


# ------------------------------------------------------------------ strict decoding

_DELETE = object()
_RAW = "__raw_json_value__"


def _payload(kind: str, path: tuple = (), value: Any = _DELETE, raw: bytes | None = None) -> bytes:
    """The golden message of ``kind`` with the field at ``path`` replaced or deleted.

    With ``raw``, the field is set to those literal bytes (e.g. ``NaN``), which orjson
    cannot produce itself.
    """
    obj = _golden_dict(kind)
    if path:
        parent = obj
        for chunk in path[:-1]:
            parent = parent[chunk]
        if raw is not None:
            parent[path[-1]] = _RAW
        elif value is _DELETE:
            del parent[path[-1]]
        else:
            parent[path[-1]] = value
    out = orjson.dumps(obj)
    if raw is not None:
        out = out.replace(b'"%s"' % _RAW.encode(), raw)
    return out


def _det(i: int, key: str, value: Any = _DELETE, raw: bytes | None = None) -> bytes:
    return _payload("detections", ("detections", i, key), value, raw)


def _trk(i: int, key: str, value: Any = _DELETE) -> bytes:
    return _payload("tracks", ("tracks", i, key), value)


def _many_detections(n: int) -> bytes:
    obj = _golden_dict("detections")
    obj["detections"] = [obj["detections"][0]] * n
    return orjson.dumps(obj)


_GOLDEN_DET = encode_detection_batch(GOLDEN["detections"])
_TEN_MB_ARRAY = b"[" + b"0," * (5 * 1024 * 1024) + b"0]"

# (decoder kind, payload, field path the message must start with, another fragment)
REJECTIONS: list[tuple[str, bytes, str, str]] = [
    ("detections", _GOLDEN_DET[:-7], "message", "not valid JSON"),
    ("detections", b"", "message", "not valid JSON"),
    ("detections", b"[1, 2, 3]", "message", "a JSON object"),
    ("detections", b'"detections"', "message", "a JSON object"),
    ("detections", _payload("detections", ("v",), 2), "v", "schema version 1"),
    ("detections", _payload("detections", ("v",), "1"), "v", "schema version 1"),
    ("detections", _payload("detections", ("v",), True), "v", "schema version 1"),
    ("detections", _payload("detections", ("v",), 1.0), "v", "schema version 1"),
    ("detections", _payload("detections", ("v",)), "v", "schema version 1"),
    ("detections", _payload("detections", ("kind",), "tracks"), "kind", "'tracks'"),
    ("tracks", _GOLDEN_DET, "kind", "'detections'"),
    ("heartbeat", _payload("heartbeat", ("kind",)), "kind", "None"),
    ("detections", _payload("detections", ("seq",)), "seq", "missing"),
    ("detections", _det(1, "confidence"), "detections[1].confidence", "missing"),
    ("tracks", _trk(2, "visibility"), "tracks[2].visibility", "missing"),
    ("ground_truth", _payload("ground_truth", ("people", 1, "covered")), "people[1].covered", ""),
    ("stats", _payload("stats", ("counters",)), "counters", "object"),
    ("detections", _payload("detections", ("colour",), 1), "colour", "unknown field"),
    ("detections", _det(1, "colour", [1, 2]), "detections[1].colour", "unknown field"),
    ("tracks", _trk(0, "name", "bob"), "tracks[0].name", "unknown field"),
    ("heartbeat", _payload("heartbeat", ("tracks",), []), "tracks", "unknown field"),
    ("detections", _payload("detections", ("stamp",), "1.0"), "stamp", "a number"),
    ("detections", _det(1, "x", "1.5"), "detections[1].x", "a number"),
    ("detections", _det(0, "x", None), "detections[0].x", "a number"),
    ("tracks", _trk(0, "vx", [0.5]), "tracks[0].vx", "a number"),
    ("detections", _payload("detections", ("seq",), True), "seq", "an integer"),
    ("detections", _payload("detections", ("seq",), 42.0), "seq", "an integer"),
    ("detections", _det(0, "x", True), "detections[0].x", "a number"),
    ("tracks", _trk(1, "id", True), "tracks[1].id", "an integer"),
    ("tracks", _trk(1, "confirmed", 1), "tracks[1].confirmed", "true or false"),
    ("heartbeat", _payload("heartbeat", ("max_id",), False), "max_id", "an integer"),
    ("stats", _payload("stats", ("counters", "in"), True), "counters.in", "an integer"),
    ("detections", _det(1, "z", raw=b"NaN"), "message", "not valid JSON"),
    ("detections", _det(1, "z", raw=b"Infinity"), "message", "not valid JSON"),
    ("detections", _det(1, "z", raw=b"-Infinity"), "message", "not valid JSON"),
    ("detections", _det(1, "z", raw=b"1e999"), "message", "not valid JSON"),
    ("detections", _det(1, "z", raw=b"-1e999"), "message", "not valid JSON"),
    ("detections", _det(1, "confidence", 1.5), "detections[1].confidence", "[0, 1]"),
    ("detections", _det(0, "confidence", -0.01), "detections[0].confidence", "[0, 1]"),
    ("tracks", _trk(2, "confidence", 2), "tracks[2].confidence", "[0, 1]"),
    ("detections", _det(0, "height", -0.1), "detections[0].height", "[0, 10]"),
    (
        "ground_truth",
        _payload("ground_truth", ("people", 0, "height"), -1.8),
        "people[0].height",
        "",
    ),
    ("detections", _det(0, "x", 1.0e5), "detections[0].x", "[-10000, 10000]"),
    ("detections", _payload("detections", ("stamp",), -1.0), "stamp", "a number in"),
    ("detections", _many_detections(MAX_ITEMS + 1), "detections", f"at most {MAX_ITEMS} items"),
    ("detections", _det(1, "appearance", [0, 256]), "detections[1].appearance[1]", "[0, 255]"),
    ("detections", _det(1, "appearance", [-1]), "detections[1].appearance[0]", "[0, 255]"),
    ("detections", _det(1, "appearance", [1, True]), "detections[1].appearance[1]", "integer"),
    (
        "detections",
        _det(1, "appearance", [0] * (MAX_APPEARANCE_BINS + 1)),
        "detections[1].appearance",
        f"at most {MAX_APPEARANCE_BINS} items",
    ),
    ("detections", _det(1, "bbox", [1, 2, 3]), "detections[1].bbox", "[u, v, width, height]"),
    ("detections", _det(1, "bbox", [1, 2, -3, 4]), "detections[1].bbox", "width, height >= 0"),
    ("detections", _det(1, "bbox", [1, 2, 3, 4, 5]), "detections[1].bbox", "at most 4 items"),
    ("detections", _det(1, "bbox", [1, 2, 3.0, 4]), "detections[1].bbox[2]", "integer"),
    ("detections", _det(1, "bbox", "1,2,3,4"), "detections[1].bbox", "an array"),
    ("detections", _det(1, "face", [0.5, "x"]), "detections[1].face[1]", "a finite number"),
    ("detections", _det(1, "face", [0.0, False]), "detections[1].face[1]", "a finite number"),
    (
        "detections",
        _det(1, "face", [0.0] * (MAX_FACE_DIMS + 1)),
        "detections[1].face",
        f"at most {MAX_FACE_DIMS} items",
    ),
    ("detections", _payload("detections", ("detections", 1), 5), "detections[1]", "JSON object"),
    ("detections", _payload("detections", ("detections",), {}), "detections", "an array"),
    ("detections", _TEN_MB_ARRAY, "message", f"{MAX_PAYLOAD_BYTES}-byte limit"),
    ("stats", _TEN_MB_ARRAY, "message", f"{MAX_PAYLOAD_BYTES}-byte limit"),
    ("detections", _payload("detections", ("sensor_id",), "k2/a"), "sensor_id", "[A-Za-z0-9_.-]"),
    ("detections", _payload("detections", ("sensor_id",), "k2_*"), "sensor_id", "[A-Za-z0-9_.-]"),
    ("detections", _payload("detections", ("sensor_id",), ""), "sensor_id", "1-128 characters"),
    ("detections", _payload("detections", ("sensor_id",), "s" * 129), "sensor_id", "1-128"),
    ("detections", _payload("detections", ("sensor_id",), 7), "sensor_id", "a name"),
    ("detections", _payload("detections", ("frame_id",), "world/**"), "frame_id", "a name"),
    ("stats", _payload("stats", ("node",), "a/b"), "node", "a name"),
    ("tracks", _trk(0, "id", 0), "tracks[0].id", "[1, 2147483647]"),
    ("tracks", _trk(0, "id", MAX_ID + 1), "tracks[0].id", "[1, 2147483647]"),
    ("tracks", _trk(0, "visibility", 3), "tracks[0].visibility", "[0, 2]"),
    ("tracks", _trk(2, "stable_id", -1), "tracks[2].stable_id", "integer in"),
    ("tracks", _trk(2, "identity", "x" * 129), "tracks[2].identity", "at most 128"),
    ("tracks", _trk(2, "identity", 5), "tracks[2].identity", "a string"),
    ("tracks", _payload("tracks", ("alive_ids",), [3, True, 9]), "alive_ids[1]", "integer"),
    ("tracks", _payload("tracks", ("alive_ids",), [3, 0]), "alive_ids[1]", "[1, 2147483647]"),
    ("heartbeat", _payload("heartbeat", ("alive_ids",), [3, False]), "alive_ids[1]", "integer"),
    ("heartbeat", _payload("heartbeat", ("alive_ids",), [1.0]), "alive_ids[0]", "integer"),
    ("heartbeat", _payload("heartbeat", ("alive_ids",), 3), "alive_ids", "an array"),
    ("heartbeat", _payload("heartbeat", ("max_id",), -1), "max_id", "[0, 2147483647]"),
    (
        "ground_truth",
        _payload("ground_truth", ("people", 0, "kind"), "robot"),
        "people[0].kind",
        "",
    ),
    ("ground_truth", _payload("ground_truth", ("people", 1, "id"), -1), "people[1].id", "integer"),
    ("stats", _payload("stats", ("counters", "in"), 1.5), "counters.in", "an integer"),
    ("stats", _payload("stats", ("rates_hz", "in"), "fast"), "rates_hz.in", "a finite number"),
    ("stats", _payload("stats", ("timings_ms",), [1.0]), "timings_ms", "an object"),
    ("stats", _payload("stats", ("host",), "h" * 256), "host", "a host name"),
    ("stats", _payload("stats", ("pid",), -1), "pid", "integer in"),
    ("stats", _payload("stats", ("uptime_s",), -5.0), "uptime_s", "a number in"),
]
REJECTION_IDS = [
    "truncated-json",
    "empty-payload",
    "array-not-object",
    "string-not-object",
    "schema-version-2",
    "schema-version-string",
    "schema-version-true",
    "schema-version-float",
    "schema-version-missing",
    "wrong-kind",
    "detections-to-track-decoder",
    "kind-missing",
    "missing-seq",
    "missing-detection-confidence",
    "missing-track-visibility",
    "missing-person-covered",
    "missing-stats-counters",
    "unknown-top-level-field",
    "unknown-detection-field",
    "unknown-track-field",
    "unknown-heartbeat-field",
    "stamp-is-string",
    "x-is-string",
    "x-is-null",
    "vx-is-list",
    "seq-is-true",
    "seq-is-float",
    "x-is-true",
    "track-id-is-true",
    "confirmed-is-int",
    "max-id-is-false",
    "counter-is-true",
    "nan-literal",
    "infinity-literal",
    "minus-infinity-literal",
    "1e999",
    "minus-1e999",
    "confidence-above-1",
    "confidence-below-0",
    "track-confidence-2",
    "negative-height",
    "negative-person-height",
    "x-beyond-10km",
    "negative-stamp",
    "too-many-detections",
    "appearance-bin-256",
    "appearance-bin-minus-1",
    "appearance-bin-bool",
    "appearance-too-many-bins",
    "bbox-3-items",
    "bbox-negative-width",
    "bbox-5-items",
    "bbox-float",
    "bbox-string",
    "face-string",
    "face-bool",
    "face-too-long",
    "detection-not-object",
    "detections-not-array",
    "10MB-payload-detections",
    "10MB-payload-stats",
    "sensor-id-slash",
    "sensor-id-star",
    "sensor-id-empty",
    "sensor-id-too-long",
    "sensor-id-int",
    "frame-id-wildcard",
    "stats-node-slash",
    "track-id-0",
    "track-id-above-int32",
    "visibility-3",
    "stable-id-negative",
    "identity-too-long",
    "identity-int",
    "alive-ids-bool",
    "alive-ids-0",
    "heartbeat-alive-ids-bool",
    "heartbeat-alive-ids-float",
    "heartbeat-alive-ids-not-array",
    "heartbeat-max-id-negative",
    "person-kind-robot",
    "person-id-negative",
    "counter-float",
    "rate-string",
    "timings-not-object",
    "host-too-long",
    "pid-negative",
    "uptime-negative",
]
assert len(REJECTIONS) == len(REJECTION_IDS)


@pytest.mark.parametrize("kind, payload, path, fragment", REJECTIONS, ids=REJECTION_IDS)
def test_decoder_rejects_with_field_path(
    kind: str, payload: bytes, path: str, fragment: str
) -> None:
    decode = CODECS[kind][1]
    with pytest.raises(WireFormatError) as info:
        decode(payload)
    message = str(info.value)
    assert message.startswith(f"{path}:"), message
    assert fragment in message, message
    assert len(message) < 400  # never echoes a whole payload


def test_oversized_payload_is_rejected_before_parsing(monkeypatch: pytest.MonkeyPatch) -> None:
    def must_not_parse(_payload: Any) -> Any:
        raise AssertionError("orjson.loads called on an oversized payload")

    monkeypatch.setattr(orjson, "loads", must_not_parse)
    for decode in DECODERS:
        with pytest.raises(WireFormatError, match=r"exceeds the 1048576-byte limit"):
            decode(_TEN_MB_ARRAY)


def test_payload_size_limit_is_inclusive() -> None:
    raw = GOLDEN_FILES["heartbeat"].read_bytes()
    padded = raw + b" " * (MAX_PAYLOAD_BYTES - len(raw))
    assert len(padded) == MAX_PAYLOAD_BYTES
    assert decode_heartbeat(padded) == GOLDEN["heartbeat"]
    with pytest.raises(WireFormatError, match=r"^message: 1048577 bytes exceeds"):
        decode_heartbeat(padded + b" ")


def test_integers_on_the_wire_decode_as_floats() -> None:
    obj = _golden_dict("detections")
    obj["stamp"] = 1700000000
    obj["detections"][1].update(x=1, face=[1, -2, 0])
    batch = decode_detection_batch(orjson.dumps(obj))
    assert type(batch.stamp) is float
    assert type(batch.detections[1].x) is float
    assert batch.detections[1].face == (1.0, -2.0, 0.0)
    assert all(type(v) is float for v in batch.detections[1].face or ())
    stats = decode_node_stats(_payload("stats", ("rates_hz", "in"), 30))
    assert type(stats.rates_hz["in"]) is float
    assert type(stats.counters["in"]) is int


def test_exactly_max_items_detections_are_accepted() -> None:
    batch = decode_detection_batch(_many_detections(MAX_ITEMS))
    assert len(batch.detections) == MAX_ITEMS
    assert batch.detections[-1] == GOLDEN["detections"].detections[0]


def test_decoder_reports_first_bad_detection_not_a_later_one() -> None:
    obj = _golden_dict("detections")
    obj["detections"][0]["height"] = -1.0
    obj["detections"][1]["height"] = -2.0
    with pytest.raises(WireFormatError, match=r"^detections\[0\]\.height:"):
        decode_detection_batch(orjson.dumps(obj))


def test_name_with_trailing_newline_is_rejected() -> None:
    with pytest.raises(WireFormatError, match=r"^sensor_id:"):
        decode_detection_batch(_payload("detections", ("sensor_id",), "k2_a\n"))


@pytest.mark.parametrize("decode", DECODERS, ids=DECODER_IDS)
def test_str_payload_with_lone_surrogate_raises_wire_format_error(
    decode: Callable[[Any], Any],
) -> None:
    with pytest.raises(WireFormatError, match=r"^message:"):
        decode('{"v":1,"kind":"\ud800"}')


# ---------------------------------------------------------------- encoders refuse NaN

_NAN, _INF = math.nan, math.inf
_D0 = GOLDEN["detections"].detections[0]
_D1 = GOLDEN["detections"].detections[1]
_T0 = GOLDEN["tracks"].tracks[0]
_P0 = GOLDEN["ground_truth"].people[0]


def _with(message: Any, **changes: Any) -> Any:
    return type(message)(**{**_fields(message), **changes})


def _fields(message: Any) -> dict[str, Any]:
    return {name: getattr(message, name) for name in message.__slots__}


NON_FINITE = [
    pytest.param("tracks", _with(GOLDEN["tracks"], stamp=_INF), "stamp", id="tracks-stamp-inf"),
    pytest.param(
        "tracks",
        _with(GOLDEN["tracks"], tracks=(_with(_T0, vx=_NAN),)),
        "vx",
        id="track-vx-nan",
    ),
    pytest.param(
        "tracks",
        _with(GOLDEN["tracks"], tracks=(_with(_T0, age=_INF),)),
        "age",
        id="track-age-inf",
    ),
    pytest.param(
        "heartbeat", _with(GOLDEN["heartbeat"], stamp=_NAN), "stamp", id="heartbeat-stamp-nan"
    ),
    pytest.param(
        "ground_truth",
        _with(GOLDEN["ground_truth"], people=(_with(_P0, height=_NAN),)),
        "height",
        id="person-height-nan",
    ),
    pytest.param(
        "ground_truth",
        _with(GOLDEN["ground_truth"], people=(_with(_P0, vy=-_INF),)),
        "vy",
        id="person-vy-minus-inf",
    ),
    pytest.param(
        "ground_truth",
        _with(GOLDEN["ground_truth"], stamp=_NAN),
        "stamp",
        id="ground-truth-stamp-nan",
    ),
    pytest.param(
        "stats",
        _with(GOLDEN["stats"], stamp=_NAN),
        "stamp",
        id="stats-stamp-nan",
    ),
    pytest.param(
        "stats",
        _with(GOLDEN["stats"], uptime_s=_INF),
        "uptime_s",
        id="stats-uptime-inf",
    ),
    pytest.param(
        "stats",
        _with(GOLDEN["stats"], rates_hz={"in": _NAN}),
        "rates_hz",
        id="stats-rate-nan",
    ),
    pytest.param(
        "stats",
        _with(GOLDEN["stats"], timings_ms={"step": _INF}),
        "timings_ms",
        id="stats-timing-inf",
    ),
]


@pytest.mark.parametrize("kind, message, field", NON_FINITE)
def test_encoder_refuses_non_finite_numbers(kind: str, message: Any, field: str) -> None:
    encode = CODECS[kind][0]
    with pytest.raises(WireFormatError) as info:
        encode(message)
    assert field in str(info.value)


def test_encoder_refuses_a_non_finite_detection_smuggled_past_its_constructor() -> None:
    detection = _with(_D0)
    object.__setattr__(detection, "x", _NAN)  # what no producer can do by building one
    with pytest.raises(WireFormatError, match="cannot encode detection: x is nan"):
        encode_detection_batch(_with(GOLDEN["detections"], detections=(detection,)))


# ------------------------------------------------- detections are checked when built

# (field, bad value, the field's path in the decoder's message)
BAD_DETECTION_FIELDS = [
    ("x", _NAN, "x"),
    ("y", -_INF, "y"),
    ("z", 2.0e4, "z"),
    ("height", -1.0, "height"),
    ("height", 10.5, "height"),
    ("confidence", _INF, "confidence"),
    ("confidence", 1.5, "confidence"),
    ("distance", -0.1, "distance"),
    ("x", "1.0", "x"),
    ("x", True, "x"),
    ("bbox", (1, 2, -3, 4), "bbox"),
    ("bbox", (1, 2, 3), "bbox"),
    ("bbox", (1, 2, 3, 1 << 21), "bbox[3]"),
    ("appearance", (1, 256), "appearance[1]"),
    ("appearance", (0,) * (MAX_APPEARANCE_BINS + 1), "appearance"),
    ("face", (0.5, _NAN), "face[1]"),
    ("face", (0.0,) * (MAX_FACE_DIMS + 1), "face"),
    ("face_confidence", 1.5, "face_confidence"),
    ("face_confidence", -0.25, "face_confidence"),
    ("face_confidence", _NAN, "face_confidence"),
    ("face_confidence", True, "face_confidence"),
]


@pytest.mark.parametrize("name, value, path", BAD_DETECTION_FIELDS)
def test_a_detection_is_checked_when_built_in_the_decoders_words(
    name: str, value: Any, path: str
) -> None:
    with pytest.raises(WireFormatError) as built:
        _with(_D1, **{name: value})
    assert str(built.value).startswith(f"Detection.{path}: ")
    numbers = value if isinstance(value, tuple) else (value,)
    if all(type(v) in (int, float) and math.isfinite(v) for v in numbers):
        # the same value on the wire (JSON has no NaN) gets the same words after the path
        obj = _golden_dict("detections")
        obj["detections"][1][name] = list(value) if isinstance(value, tuple) else value
        with pytest.raises(WireFormatError) as decoded:
            decode_detection_batch(orjson.dumps(obj))
        assert str(decoded.value).startswith(f"detections[1].{path}: ")
        assert str(built.value).split(": ", 1)[1] == str(decoded.value).split(": ", 1)[1]


@pytest.mark.parametrize(
    "name, value, path",
    [
        ("stamp", _NAN, "stamp"),
        ("stamp", -1.0, "stamp"),
        ("seq", -1, "seq"),
        ("seq", 1.0, "seq"),
        ("sensor_id", "k2 a", "sensor_id"),
        ("sensor_id", "", "sensor_id"),
        ("frame_id", "s" * (MAX_NAME_LEN + 1), "frame_id"),
        ("detections", [_D0], "detections"),
        ("detections", (_D0, (1.0, 2.0)), "detections[1]"),
        ("detections", (_D0,) * (MAX_ITEMS + 1), "detections"),
    ],
)
def test_a_detection_batch_is_checked_when_built(name: str, value: Any, path: str) -> None:
    with pytest.raises(WireFormatError, match=rf"^DetectionBatch\.{re.escape(path)}: "):
        _with(GOLDEN["detections"], **{name: value})


def test_face_confidence_round_trips_with_its_face() -> None:
    with_face = _with(_D1, face=(0.6, -0.8), face_confidence=0.375)
    batch = _with(GOLDEN["detections"], detections=(_D0, with_face))
    payload = encode_detection_batch(batch)
    assert orjson.loads(payload)["detections"][1]["face_confidence"] == 0.375
    assert "face_confidence" not in orjson.loads(payload)["detections"][0]
    decoded = decode_detection_batch(payload)
    assert decoded == batch
    assert decoded.detections[1].face_confidence == 0.375
    assert decoded.detections[0].face_confidence is None
    for edge in (0, 1):  # integers on the wire are numbers too
        obj = _golden_dict("detections")
        obj["detections"][1]["face_confidence"] = edge
        assert decode_detection_batch(orjson.dumps(obj)).detections[1].face_confidence == edge


@pytest.mark.parametrize(
    "value, words",
    [
        (1.5, "expected a number in [0, 1], got 1.5"),
        (-0.5, "expected a number in [0, 1], got -0.5"),
        ("0.5", "expected a number, got '0.5'"),
        (False, "expected a number, got False"),
        (None, "expected a number, got None"),
    ],
)
def test_decoder_rejects_a_bad_face_confidence_naming_it(value: Any, words: str) -> None:
    obj = _golden_dict("detections")
    obj["detections"][1]["face_confidence"] = value
    with pytest.raises(WireFormatError) as info:
        decode_detection_batch(orjson.dumps(obj))
    assert str(info.value) == f"detections[1].face_confidence: {words}"


def test_face_confidence_without_a_face_is_refused() -> None:
    with pytest.raises(WireFormatError, match=r"^Detection\.face_confidence: expected a value"):
        _with(_D0, face_confidence=0.5)
    obj = _golden_dict("detections")
    assert "face" not in obj["detections"][0]
    obj["detections"][0]["face_confidence"] = 0.5
    with pytest.raises(WireFormatError, match=r"^detections\[0\]\.face_confidence: "):
        decode_detection_batch(orjson.dumps(obj))


def test_nan_face_confidence_cannot_be_encoded() -> None:
    detection = _with(_D1, face_confidence=0.5)
    object.__setattr__(detection, "face_confidence", _NAN)  # no producer can build this
    batch = _with(GOLDEN["detections"], detections=(detection,))
    with pytest.raises(WireFormatError, match="face_confidence"):
        encode_detection_batch(batch)


def test_valid_detections_of_any_real_number_type_are_built() -> None:
    import numpy as np

    d = Detection(x=np.float64(1.0), y=2, z=np.float32(0.9), height=1.7, confidence=1, distance=0)
    assert d.y == 2 and d.confidence == 1
    batch = DetectionBatch("k2_a", np.int64(3), 1.0e9, "world", (d,))  # type: ignore[arg-type]
    assert batch.seq == 3


# --------------------------------------------------------------------- key routing


@pytest.mark.parametrize(
    "key, expected",
    [
        ("opt/default/detections/k2_a", decode_detection_batch),
        ("opt/gallery/detections/*", decode_detection_batch),
        ("opt/default/tracks", decode_track_batch),
        ("opt/default/tracks/smoothed", decode_track_batch),
        ("opt/default/ground_truth", decode_ground_truth),
        ("opt/default/stats/tracker", decode_node_stats),
        ("opt/default/heartbeat", decode_heartbeat),
        ("opt/default/unknown", None),
        ("opt/default/Tracks", None),
        ("opt/default/tracks_smoothed", None),
        ("opt/default", None),
        ("opt", None),
        ("", None),
        ("ros/default/tracks", None),
        ("default/tracks/smoothed", None),
    ],
    ids=[
        "detections",
        "detections-wildcard",
        "tracks",
        "tracks-smoothed",
        "ground-truth",
        "stats",
        "heartbeat",
        "unknown-topic",
        "wrong-case",
        "similar-topic",
        "no-topic",
        "prefix-only",
        "empty",
        "other-prefix",
        "no-prefix",
    ],
)
def test_decoder_for_key(key: str, expected: Callable | None) -> None:
    assert decoder_for_key(key) is expected


TOPIC_KIND = {"config": "config_update"}  # other topics carry the kind of the same name


def test_every_topic_decodes_its_own_golden_message() -> None:
    assert {TOPIC_KIND.get(t, t) for t in TOPICS} | {"config_ack"} == set(GOLDEN)
    for topic in TOPICS:
        kind = TOPIC_KIND.get(topic, topic)
        decode = decoder_for_key(f"opt/site/{topic}/x")
        assert decode is not None
        assert decode(GOLDEN_FILES[kind].read_bytes()) == GOLDEN[kind]
    ack = decoder_for_key("opt/site/config/tracker/ack")
    assert ack is decode_config_ack
    assert ack(GOLDEN_FILES["config_ack"].read_bytes()) == GOLDEN["config_ack"]


# ------------------------------------------------------------------------ micro-fuzz

json_scalars = (
    st.none()
    | st.booleans()
    | st.integers(-(1 << 63), (1 << 64) - 1)
    | any_finite
    | st.text(max_size=20)
)
json_values = st.recursive(
    json_scalars,
    lambda children: (
        st.lists(children, max_size=5)
        | st.dictionaries(st.text(max_size=10), children, max_size=5)
    ),
    max_leaves=25,
)


def _assert_rejects_or_valid(kind: str, payload: bytes | str) -> None:
    encode, decode, cls = CODECS[kind]
    try:
        message = decode(payload)
    except WireFormatError:
        return
    assert type(message) is cls
    raw = encode(message)  # a message the decoder accepted is encodable...
    assert decode(raw) == message  # ...and survives its own round trip
    assert encode(decode(raw)) == raw


FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@FUZZ
@given(st.binary(max_size=300))
def test_fuzz_arbitrary_bytes(payload: bytes) -> None:
    for kind in CODECS:
        _assert_rejects_or_valid(kind, payload)


@FUZZ
@given(st.text(max_size=200))
def test_fuzz_arbitrary_text(payload: str) -> None:
    for kind in CODECS:
        _assert_rejects_or_valid(kind, payload)


@FUZZ
@given(json_values)
def test_fuzz_arbitrary_json_values(value: Any) -> None:
    payload = orjson.dumps(value)
    for kind in CODECS:
        _assert_rejects_or_valid(kind, payload)


def _all_paths(obj: Any, prefix: tuple = ()) -> list[tuple]:
    paths = [prefix] if prefix else []
    if isinstance(obj, dict):
        for key, value in obj.items():
            paths.extend(_all_paths(value, (*prefix, key)))
    elif isinstance(obj, list):
        for i, value in enumerate(obj):
            paths.extend(_all_paths(value, (*prefix, i)))
    return paths


_FIELD_PATHS = [(kind, path) for kind in GOLDEN for path in _all_paths(_golden_dict(kind))]


@FUZZ
@given(st.sampled_from(_FIELD_PATHS), json_values, st.booleans())
def test_fuzz_one_field_of_a_valid_message(target: tuple, value: Any, delete: bool) -> None:
    # Mutating one field of a valid message reaches the per-field checks, which
    # arbitrary bytes almost never do.
    kind, path = target
    payload = _payload(kind, path, _DELETE if delete else value)
    _assert_rejects_or_valid(kind, payload)


@FUZZ
@given(
    st.sampled_from(list(CODECS)),
    st.dictionaries(
        st.sampled_from(
            sorted(
                data_codec._DETECTION_BATCH_KEYS
                | data_codec._TRACK_BATCH_KEYS
                | control_codec._STATS_KEYS
                | data_codec._GROUND_TRUTH_KEYS
                | {"junk"}
            )
        ),
        json_values,
        max_size=8,
    ),
)
def test_fuzz_objects_with_valid_header(kind: str, fields: dict) -> None:
    payload = orjson.dumps({**fields, "v": SCHEMA_VERSION, "kind": kind})
    _assert_rejects_or_valid(kind, payload)
