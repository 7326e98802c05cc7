"""Builders and strict parsers for the data messages: detections, tracks, ground truth.

One encoder and one decoder per kind, on the envelope and field readers of
:mod:`openptrack_py.messages.fields`. Encoders omit optional fields that are ``None``
and refuse NaN or infinities; decoders check every field and raise
:class:`~openptrack_py.errors.WireFormatError` naming the first one that is wrong. They
never return a partially valid message.
"""

from __future__ import annotations

import math
from typing import Any

from openptrack_py.errors import WireFormatError
from openptrack_py.messages.detection import Detection, DetectionBatch
from openptrack_py.messages.fields import (
    MAX_APPEARANCE_BINS,
    MAX_COORD_M,
    MAX_FACE_DIMS,
    MAX_HEIGHT_M,
    MAX_ID,
    MAX_ITEMS,
    MAX_NAME_LEN,
    MAX_STAMP_S,
    SCHEMA_VERSION,
    check_finite,
    check_keys,
    dump_message,
    fail,
    parse_message,
    read_bool,
    read_float,
    read_int,
    read_int_list,
    read_list,
    read_name,
)
from openptrack_py.messages.ground_truth import GroundTruthFrame, PersonState
from openptrack_py.messages.track import Track, TrackBatch, Visibility

# ------------------------------------------------------------------------ detections

_DETECTION_KEYS = frozenset(
    {
        "x",
        "y",
        "z",
        "height",
        "confidence",
        "distance",
        "bbox",
        "appearance",
        "face",
        "face_confidence",
    }
)
_DETECTION_BATCH_KEYS = frozenset(
    {"v", "kind", "sensor_id", "seq", "stamp", "frame_id", "detections"}
)


def encode_detection_batch(batch: DetectionBatch) -> bytes:
    """Encode a :class:`DetectionBatch` to wire bytes.

    Raises
    ------
    WireFormatError
        If a number is NaN or infinite.
    """
    dets = []
    for d in batch.detections:
        check_finite(
            "detection",
            (d.x, d.y, d.z, d.height, d.confidence, d.distance),
            "x y z height confidence distance",
        )
        item: dict[str, Any] = {
            "x": d.x,
            "y": d.y,
            "z": d.z,
            "height": d.height,
            "confidence": d.confidence,
            "distance": d.distance,
        }
        if d.bbox is not None:
            item["bbox"] = list(d.bbox)
        if d.appearance is not None:
            item["appearance"] = list(d.appearance)
        if d.face is not None:
            if not all(math.isfinite(v) for v in d.face):
                raise WireFormatError("cannot encode detection: face has a non-finite value")
            item["face"] = list(d.face)
        if d.face_confidence is not None:
            check_finite("detection", (d.face_confidence,), "face_confidence")
            item["face_confidence"] = d.face_confidence
        dets.append(item)
    check_finite("detection batch", (batch.stamp,), "stamp")
    return dump_message(
        {
            "v": SCHEMA_VERSION,
            "kind": "detections",
            "sensor_id": batch.sensor_id,
            "seq": batch.seq,
            "stamp": batch.stamp,
            "frame_id": batch.frame_id,
            "detections": dets,
        }
    )


def _decode_detection(obj: Any, path: str) -> Detection:
    check_keys(obj, _DETECTION_KEYS, path)
    bbox = appearance = face = face_confidence = None
    if "bbox" in obj:
        box = read_int_list(obj, "bbox", path, -(1 << 20), 1 << 20, 4)
        if len(box) != 4 or box[2] < 0 or box[3] < 0:
            raise fail(path + "bbox", "[u, v, width, height] with width, height >= 0", box)
        bbox = box
    if "appearance" in obj:
        appearance = read_int_list(obj, "appearance", path, 0, 255, MAX_APPEARANCE_BINS)
    if "face" in obj:
        values = read_list(obj, "face", path, MAX_FACE_DIMS)
        for i, v in enumerate(values):
            if (type(v) is not float and type(v) is not int) or not math.isfinite(v):
                raise fail(f"{path}face[{i}]", "a finite number", v)
        face = tuple(float(v) for v in values)
    if "face_confidence" in obj:
        face_confidence = read_float(obj, "face_confidence", path, 0.0, 1.0)
        if face is None:
            raise fail(path + "face_confidence", "a value only alongside face", face_confidence)
    try:  # fast path: six floats, whose ranges the constructor checks
        numbers = (obj["x"], obj["y"], obj["z"], obj["height"], obj["confidence"], obj["distance"])
        if all(type(v) is float for v in numbers):
            return Detection(
                *numbers,
                bbox=bbox,
                appearance=appearance,
                face=face,
                face_confidence=face_confidence,
            )
    except (KeyError, WireFormatError):
        pass  # the field by field reading below names the first bad one
    return Detection(
        x=read_float(obj, "x", path, -MAX_COORD_M, MAX_COORD_M),
        y=read_float(obj, "y", path, -MAX_COORD_M, MAX_COORD_M),
        z=read_float(obj, "z", path, -MAX_COORD_M, MAX_COORD_M),
        height=read_float(obj, "height", path, 0.0, MAX_HEIGHT_M),
        confidence=read_float(obj, "confidence", path, 0.0, 1.0),
        distance=read_float(obj, "distance", path, 0.0, MAX_COORD_M),
        bbox=bbox,
        appearance=appearance,
        face=face,
        face_confidence=face_confidence,
    )


def decode_detection_batch(payload: bytes | bytearray | memoryview | str) -> DetectionBatch:
    """Decode and validate wire bytes into a :class:`DetectionBatch`.

    Raises
    ------
    WireFormatError
        Naming the first field that is missing, of the wrong type, not finite, out of
        range or too large.
    """
    obj = parse_message(payload, "detections", _DETECTION_BATCH_KEYS)
    items = read_list(obj, "detections", "")
    return DetectionBatch(
        sensor_id=read_name(obj, "sensor_id", ""),
        seq=read_int(obj, "seq", ""),
        stamp=read_float(obj, "stamp", "", 0.0, MAX_STAMP_S),
        frame_id=read_name(obj, "frame_id", ""),
        detections=tuple(_decode_detection(d, f"detections[{i}].") for i, d in enumerate(items)),
    )


# ---------------------------------------------------------------------------- tracks

_TRACK_KEYS = frozenset(
    {
        "id",
        "x",
        "y",
        "z",
        "height",
        "vx",
        "vy",
        "age",
        "confidence",
        "visibility",
        "confirmed",
        "stable_id",
        "identity",
    }
)
_TRACK_BATCH_KEYS = frozenset(
    {"v", "kind", "stamp", "seq", "frame_id", "tracks", "alive_ids", "max_id", "source"}
)
_SOURCE_KEYS = frozenset({"sensor_id", "seq", "stamp"})


def track_dict(t: Track) -> dict[str, Any]:
    """A track as the JSON object used on the wire (optional fields only when set).

    Raises
    ------
    WireFormatError
        If a number is NaN or infinite.
    """
    check_finite(
        "track",
        (t.x, t.y, t.z, t.height, t.vx, t.vy, t.age, t.confidence),
        "x y z height vx vy age confidence",
    )
    item: dict[str, Any] = {
        "id": t.id,
        "x": t.x,
        "y": t.y,
        "z": t.z,
        "height": t.height,
        "vx": t.vx,
        "vy": t.vy,
        "age": t.age,
        "confidence": t.confidence,
        "visibility": int(t.visibility),
        "confirmed": t.confirmed,
    }
    if t.stable_id is not None:
        item["stable_id"] = t.stable_id
    if t.identity is not None:
        item["identity"] = t.identity
    return item


def encode_track_batch(batch: TrackBatch) -> bytes:
    """Encode a :class:`TrackBatch` to wire bytes.

    Raises
    ------
    WireFormatError
        If a number is NaN or infinite.
    """
    check_finite("track batch", (batch.stamp,), "stamp")
    obj: dict[str, Any] = {
        "v": SCHEMA_VERSION,
        "kind": "tracks",
        "stamp": batch.stamp,
        "seq": batch.seq,
        "frame_id": batch.frame_id,
        "tracks": [track_dict(t) for t in batch.tracks],
        "alive_ids": list(batch.alive_ids),
        "max_id": batch.max_id,
    }
    if batch.source is not None:
        sensor_id, seq, stamp = batch.source
        check_finite("track batch", (stamp,), "source.stamp")
        obj["source"] = {"sensor_id": sensor_id, "seq": seq, "stamp": stamp}
    return dump_message(obj)


def _decode_track(obj: Any, path: str) -> Track:
    check_keys(obj, _TRACK_KEYS, path)
    confirmed = read_bool(obj, "confirmed", path, default=True)
    stable_id = read_int(obj, "stable_id", path, 0, MAX_ID) if "stable_id" in obj else None
    identity = None
    if "identity" in obj:
        identity = obj["identity"]
        if type(identity) is not str or len(identity) > MAX_NAME_LEN:
            raise fail(
                path + "identity", f"a string of at most {MAX_NAME_LEN} characters", identity
            )
    return Track(
        id=read_int(obj, "id", path, 1, MAX_ID),
        x=read_float(obj, "x", path, -MAX_COORD_M, MAX_COORD_M),
        y=read_float(obj, "y", path, -MAX_COORD_M, MAX_COORD_M),
        z=read_float(obj, "z", path, -MAX_COORD_M, MAX_COORD_M),
        height=read_float(obj, "height", path, 0.0, MAX_HEIGHT_M),
        vx=read_float(obj, "vx", path, -1.0e3, 1.0e3),
        vy=read_float(obj, "vy", path, -1.0e3, 1.0e3),
        age=read_float(obj, "age", path, 0.0, 1.0e9),
        confidence=read_float(obj, "confidence", path, 0.0, 1.0),
        visibility=Visibility(read_int(obj, "visibility", path, 0, 2)),
        confirmed=confirmed,
        stable_id=stable_id,
        identity=identity,
    )


def decode_track_batch(payload: bytes | bytearray | memoryview | str) -> TrackBatch:
    """Decode and validate wire bytes into a :class:`TrackBatch`.

    Raises
    ------
    WireFormatError
        Naming the first invalid field.
    """
    obj = parse_message(payload, "tracks", _TRACK_BATCH_KEYS)
    items = read_list(obj, "tracks", "")
    return TrackBatch(
        stamp=read_float(obj, "stamp", "", 0.0, MAX_STAMP_S),
        seq=read_int(obj, "seq", ""),
        frame_id=read_name(obj, "frame_id", ""),
        tracks=tuple(_decode_track(t, f"tracks[{i}].") for i, t in enumerate(items)),
        alive_ids=read_int_list(obj, "alive_ids", "", 1, MAX_ID, MAX_ITEMS),
        max_id=read_int(obj, "max_id", "", 0, MAX_ID),
        source=_decode_source(obj.get("source")),
    )


def _decode_source(obj: Any) -> tuple[str, int, float] | None:
    if obj is None:
        return None
    check_keys(obj, _SOURCE_KEYS, "source.")
    return (
        read_name(obj, "sensor_id", "source."),
        read_int(obj, "seq", "source."),
        read_float(obj, "stamp", "source.", 0.0, MAX_STAMP_S),
    )


# ---------------------------------------------------------------------- ground truth

_PERSON_KEYS = frozenset({"id", "x", "y", "height", "vx", "vy", "kind", "covered"})
_GROUND_TRUTH_KEYS = frozenset({"v", "kind", "stamp", "seq", "people"})
_PERSON_KINDS = ("adult", "child")


def encode_ground_truth(frame: GroundTruthFrame) -> bytes:
    """Encode a :class:`GroundTruthFrame` to wire bytes."""
    check_finite("ground truth", (frame.stamp,), "stamp")
    people = []
    for p in frame.people:
        check_finite("person", (p.x, p.y, p.height, p.vx, p.vy), "x y height vx vy")
        people.append(
            {
                "id": p.id,
                "x": p.x,
                "y": p.y,
                "height": p.height,
                "vx": p.vx,
                "vy": p.vy,
                "kind": p.kind,
                "covered": p.covered,
            }
        )
    return dump_message(
        {
            "v": SCHEMA_VERSION,
            "kind": "ground_truth",
            "stamp": frame.stamp,
            "seq": frame.seq,
            "people": people,
        }
    )


def _decode_person(obj: Any, path: str) -> PersonState:
    check_keys(obj, _PERSON_KEYS, path)
    kind = obj.get("kind")
    if kind not in _PERSON_KINDS:
        raise fail(path + "kind", " or ".join(map(repr, _PERSON_KINDS)), kind)
    covered = read_bool(obj, "covered", path)
    return PersonState(
        id=read_int(obj, "id", path),
        x=read_float(obj, "x", path, -MAX_COORD_M, MAX_COORD_M),
        y=read_float(obj, "y", path, -MAX_COORD_M, MAX_COORD_M),
        height=read_float(obj, "height", path, 0.0, MAX_HEIGHT_M),
        vx=read_float(obj, "vx", path, -1.0e3, 1.0e3),
        vy=read_float(obj, "vy", path, -1.0e3, 1.0e3),
        kind=kind,
        covered=covered,
    )


def decode_ground_truth(payload: bytes | bytearray | memoryview | str) -> GroundTruthFrame:
    """Decode and validate wire bytes into a :class:`GroundTruthFrame`.

    Raises
    ------
    WireFormatError
        Naming the first invalid field.
    """
    obj = parse_message(payload, "ground_truth", _GROUND_TRUTH_KEYS)
    items = read_list(obj, "people", "")
    return GroundTruthFrame(
        stamp=read_float(obj, "stamp", "", 0.0, MAX_STAMP_S),
        seq=read_int(obj, "seq", ""),
        people=tuple(_decode_person(p, f"people[{i}].") for i, p in enumerate(items)),
    )
