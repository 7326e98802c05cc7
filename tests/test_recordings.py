"""Recording files: MCAP with schemas and metadata, JSON lines, damage, files being written."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from openptrack_py.calibration.files import SensorCalibration, entry_payload
from openptrack_py.config import Pose
from openptrack_py.messages import (
    Detection,
    DetectionBatch,
    Track,
    TrackBatch,
)
from openptrack_py.messages.codec import (
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
from openptrack_py.messages.config_update import ConfigAck, ConfigUpdate
from openptrack_py.messages.ground_truth import GroundTruthFrame, PersonState
from openptrack_py.messages.stats import NodeStats
from openptrack_py.messages.track import Heartbeat
from openptrack_py.recordings import SCHEMAS, McapWriter, open_writer, read_recording

T0 = 1_764_000_000.0

DETECTIONS = DetectionBatch(
    "k2_a", 7, T0, "world",
    (Detection(x=1.5, y=2.0, z=0.9, height=1.75, confidence=0.8, distance=3.2,
               bbox=(10, 20, 30, 60), appearance=(1, 2, 3), face=(0.1, -0.2),
               face_confidence=0.7),),
)  # fmt: skip
TRACKS = TrackBatch(
    T0, 3, "world",
    (Track(id=4, x=1.0, y=2.0, z=0.9, height=1.7, vx=0.1, vy=0.0, age=2.5, confidence=0.9,
           visibility=1, stable_id=10004, identity="Ada"),),
    (4,), 4, ("k2_a", 7, T0),
)  # fmt: skip
TRUTH = GroundTruthFrame(T0, 9, (PersonState(1, 1.0, 2.0, 1.7, 0.5, 0.0, "adult", True),))

MESSAGES = [
    ("opt/default/detections/k2_a", encode_detection_batch(DETECTIONS), decode_detection_batch),
    ("opt/default/tracks", encode_track_batch(TRACKS), decode_track_batch),
    ("opt/default/ground_truth", encode_ground_truth(TRUTH), decode_ground_truth),
    ("opt/default/heartbeat", encode_heartbeat(Heartbeat(T0, 1, (4,), 4)), decode_heartbeat),
    ("opt/default/stats/tracker",
     encode_node_stats(NodeStats("tracker", T0, 3.0, {"in": 5}, {"in": 1.0}, {"step": 1.2})),
     decode_node_stats),
    ("opt/default/config/tracker",
     encode_config_update(ConfigUpdate("r1", {"max_tracks": 5})), decode_config_update),
    ("opt/default/config/tracker/ack",
     encode_config_ack(ConfigAck("r1", "tracker", True, "", {})), decode_config_ack),
    ("opt/default/calibration/k2_a",
     entry_payload("k2_a", SensorCalibration(pose=Pose(x=1.0, z=2.5))), None),
]  # fmt: skip
"""Every kind of message a site sends, with its decoder."""


def _write(path: Path, count: int = 1, **kw: object) -> None:
    writer = open_writer(path, {"openptrack": {"site": "default"}}, **kw)  # type: ignore[arg-type]
    for i in range(count):
        for n, (key, payload, _) in enumerate(MESSAGES):
            writer.write(T0 + i + n / 100, key, payload)
    writer.close()


@pytest.mark.parametrize("suffix", [".mcap", ".jsonl"])
def test_every_kind_of_message_round_trips(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"run{suffix}"
    _write(path)
    recording = read_recording(path)
    got = list(recording)
    assert recording.stopped is None
    assert [m.key for m in got] == [key for key, _, _ in MESSAGES]
    for message, (key, payload, decode) in zip(got, MESSAGES, strict=True):
        if decode is not None:
            assert decode(message.payload) == decode(payload), key
        assert json.loads(message.payload) == json.loads(payload)
    assert [m.received for m in got] == pytest.approx([T0 + n / 100 for n in range(len(got))])
    assert got[0].topic == "detections/k2_a" and got[0].site == "default"
    if suffix == ".mcap":
        assert recording.metadata == {"openptrack": {"site": "default"}}


def test_the_mcap_reader_lists_every_channel_with_its_schema(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    _write(path, count=3)
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics.message_count == 3 * len(MESSAGES)
        channels = {c.topic: c for c in summary.channels.values()}
        assert set(channels) == {key for key, _, _ in MESSAGES}
        for topic, channel in channels.items():
            schema = summary.schemas[channel.schema_id]
            kind = topic.split("/")[2]
            assert channel.message_encoding == "json"
            assert schema.encoding == "jsonschema"
            assert json.loads(schema.data) == SCHEMAS[kind]
        messages = list(reader.iter_messages())
        assert len(messages) == 3 * len(MESSAGES)
        assert [m.name for m in reader.iter_metadata()] == ["openptrack"]


def test_the_schemas_describe_what_the_encoders_write() -> None:
    """Every field an encoder writes is a property of its schema (and its kind matches)."""
    for key, payload, _ in MESSAGES:
        kind = key.split("/")[2]
        schema, obj = SCHEMAS[kind], json.loads(payload)
        props = schema["properties"]
        if schema.get("additionalProperties") is False:
            assert set(obj) <= set(props), (kind, set(obj) - set(props))
        assert set(schema["required"]) <= set(obj), kind


@pytest.mark.parametrize("suffix", [".mcap", ".jsonl"])
def test_a_cut_recording_gives_everything_before_the_cut_and_says_where(
    tmp_path: Path, suffix: str
) -> None:
    whole = tmp_path / f"whole{suffix}"
    _write(whole, count=50, **({"flush_every_s": 0.0} if suffix == ".mcap" else {}))
    data = whole.read_bytes()
    total = len(list(read_recording(whole)))
    cut = tmp_path / f"cut{suffix}"
    inside_a_line = data.index(b"\n", int(len(data) * 0.6)) - 5  # or inside a chunk
    cut.write_bytes(data[:inside_a_line])
    recording = read_recording(cut)
    got = list(recording)
    assert 0.4 * total < len(got) < total
    assert recording.stopped is not None and str(cut) in recording.stopped
    assert [m.payload for m in got] == [m.payload for m in list(read_recording(whole))[: len(got)]]


def test_corrupt_bytes_stop_the_reading_there(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    _write(path, count=50, flush_every_s=0.0)
    data = bytearray(path.read_bytes())
    middle = len(data) // 2
    data[middle : middle + 64] = b"\xff" * 64
    path.write_bytes(bytes(data))
    recording = read_recording(path)
    got = list(recording)
    assert 0 < len(got) < 50 * len(MESSAGES)
    assert "corrupt" in (recording.stopped or "")


def test_a_recording_being_written_can_be_read(tmp_path: Path) -> None:
    path = tmp_path / "live.mcap"
    writer = McapWriter(path, flush_every_s=0.0)
    for i in range(20):
        writer.write(T0 + i, "opt/default/tracks", encode_track_batch(TRACKS))
    writer.flush()
    recording = read_recording(path)
    assert len(list(recording)) == 20
    assert "still being written, or cut" in (recording.stopped or "")
    writer.write(T0 + 20, "opt/default/tracks", encode_track_batch(TRACKS))
    writer.close()
    recording = read_recording(path)
    assert len(list(recording)) == 21 and recording.stopped is None
