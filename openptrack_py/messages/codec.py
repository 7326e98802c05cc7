"""Encoders and strict decoders for every message that crosses a process.

Wire form: one compact JSON object (orjson) whose first two keys are the schema version
``"v"`` and the message ``"kind"``. Encoders omit optional fields that are ``None``.
Decoders check the size of the payload before parsing, then the type, finiteness and
range of every field, and raise :class:`~openptrack_py.errors.WireFormatError` naming the
first field that is wrong (e.g. ``detections[3].confidence``). They never return a
partially valid message.
"""

from __future__ import annotations

import math
import re
from typing import Any

import orjson

from openptrack_py.errors import WireFormatError
from openptrack_py.messages.config_update import ConfigAck, ConfigUpdate
from openptrack_py.messages.detection import Detection, DetectionBatch
from openptrack_py.messages.ground_truth import GroundTruthFrame, PersonState
from openptrack_py.messages.stats import NodeStats
from openptrack_py.messages.track import Heartbeat, Track, TrackBatch, Visibility

SCHEMA_VERSION = 1
MAX_PAYLOAD_BYTES = 1 << 20
"""Payloads above 1 MiB are rejected before parsing."""
MAX_ITEMS = 2000
"""Largest number of detections, tracks or people in one message."""
MAX_APPEARANCE_BINS = 256
MAX_FACE_DIMS = 1024
MAX_COORD_M = 1.0e4
"""Positions beyond 10 km are not people in a room: rejected as corrupt."""
MAX_NAME_LEN = 128

_NAME_RE = re.compile(r"[A-Za-z0-9_.\-]+")
_MAX_INT = (1 << 63) - 1


# ----------------------------------------------------------------------------- readers


def _fail(path: str, expected: str, value: Any) -> WireFormatError:
    shown = repr(value)
    if len(shown) > 60:
        shown = shown[:57] + "..."
    return WireFormatError(f"{path}: expected {expected}, got {shown}")


def _float(obj: dict, key: str, path: str, lo: float = -math.inf, hi: float = math.inf) -> float:
    try:
        value = obj[key]
    except KeyError:
        raise WireFormatError(f"{path}{key}: missing") from None
    kind = type(value)
    if kind is not float and kind is not int:
        raise _fail(path + key, "a number", value)
    value = float(value)
    if not lo <= value <= hi:  # also rejects NaN
        if math.isnan(value) or math.isinf(value):
            raise _fail(path + key, "a finite number", value)
        raise _fail(path + key, f"a number in [{lo:g}, {hi:g}]", value)
    return value


def _int(obj: dict, key: str, path: str, lo: int = 0, hi: int = _MAX_INT) -> int:
    try:
        value = obj[key]
    except KeyError:
        raise WireFormatError(f"{path}{key}: missing") from None
    if type(value) is not int:
        raise _fail(path + key, "an integer", value)
    if not lo <= value <= hi:
        raise _fail(path + key, f"an integer in [{lo}, {hi}]", value)
    return value


def _bool(obj: dict, key: str, path: str, default: bool | None = None) -> bool:
    value = obj.get(key, default)
    if type(value) is not bool:
        raise _fail(path + key, "true or false", value)
    return value


def _name(obj: dict, key: str, path: str) -> str:
    try:
        value = obj[key]
    except KeyError:
        raise WireFormatError(f"{path}{key}: missing") from None
    if (
        type(value) is not str
        or not 0 < len(value) <= MAX_NAME_LEN
        or not _NAME_RE.fullmatch(value)
    ):
        raise _fail(
            path + key, f"a name of 1-{MAX_NAME_LEN} characters from [A-Za-z0-9_.-]", value
        )
    return value


def _list(obj: dict, key: str, path: str, max_len: int = MAX_ITEMS) -> list:
    try:
        value = obj[key]
    except KeyError:
        raise WireFormatError(f"{path}{key}: missing") from None
    if type(value) is not list:
        raise _fail(path + key, "an array", value)
    if len(value) > max_len:
        raise WireFormatError(f"{path}{key}: at most {max_len} items allowed, got {len(value)}")
    return value


def _int_list(obj: dict, key: str, path: str, lo: int, hi: int, max_len: int) -> tuple[int, ...]:
    items = _list(obj, key, path, max_len)
    # Fast path first (bool is an int subclass, hence the exact type test).
    exact_ints = all(type(v) is int for v in items)
    if exact_ints and (not items or (lo <= min(items) and max(items) <= hi)):
        return tuple(items)
    for i, v in enumerate(items):
        if type(v) is not int or not lo <= v <= hi:
            raise _fail(f"{path}{key}[{i}]", f"an integer in [{lo}, {hi}]", v)
    raise AssertionError("unreachable")  # pragma: no cover


def _check_keys(obj: Any, allowed: frozenset[str], path: str) -> None:
    if type(obj) is not dict:
        raise _fail(path.rstrip(".") or "message", "a JSON object", obj)
    extra = obj.keys() - allowed
    if extra:
        raise WireFormatError(
            f"{path}{sorted(extra)[0]}: unknown field (allowed: {', '.join(sorted(allowed))})"
        )


def _parse(payload: bytes | bytearray | memoryview | str, kind: str, keys: frozenset[str]) -> dict:
    if isinstance(payload, str):
        try:
            payload = payload.encode()
        except UnicodeEncodeError as exc:
            raise WireFormatError(f"message: not valid UTF-8 ({exc.reason})") from None
    size = len(payload)
    if size > MAX_PAYLOAD_BYTES:
        raise WireFormatError(f"message: {size} bytes exceeds the {MAX_PAYLOAD_BYTES}-byte limit")
    try:
        obj = orjson.loads(payload)
    except orjson.JSONDecodeError as exc:
        raise WireFormatError(f"message: not valid JSON ({exc})") from None
    if type(obj) is not dict:
        raise _fail("message", "a JSON object", obj)
    version = obj.get("v")
    if version != SCHEMA_VERSION or type(version) is not int:
        raise _fail("v", f"schema version {SCHEMA_VERSION}", version)
    if obj.get("kind") != kind:
        raise _fail("kind", repr(kind), obj.get("kind"))
    _check_keys(obj, keys, "")
    return obj


def _dumps(obj: dict) -> bytes:
    try:
        return orjson.dumps(obj)
    except (TypeError, orjson.JSONEncodeError) as exc:
        raise WireFormatError(f"cannot encode {obj.get('kind')}: {exc}") from None


def _check_finite(kind: str, values: tuple[float, ...], names: str) -> None:
    # Encoders refuse NaN/inf so that a bad number never reaches the wire.
    for name, value in zip(names.split(), values, strict=True):
        if not math.isfinite(value):
            raise WireFormatError(f"cannot encode {kind}: {name} is {value}")


# ------------------------------------------------------------------------ detections

_DETECTION_KEYS = frozenset(
    {"x", "y", "z", "height", "confidence", "distance", "bbox", "appearance", "face"}
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
        _check_finite(
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
        dets.append(item)
    _check_finite("detection batch", (batch.stamp,), "stamp")
    return _dumps(
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
    _check_keys(obj, _DETECTION_KEYS, path)
    bbox = appearance = face = None
    if "bbox" in obj:
        box = _int_list(obj, "bbox", path, -(1 << 20), 1 << 20, 4)
        if len(box) != 4 or box[2] < 0 or box[3] < 0:
            raise _fail(path + "bbox", "[u, v, width, height] with width, height >= 0", box)
        bbox = box
    if "appearance" in obj:
        appearance = _int_list(obj, "appearance", path, 0, 255, MAX_APPEARANCE_BINS)
    if "face" in obj:
        values = _list(obj, "face", path, MAX_FACE_DIMS)
        for i, v in enumerate(values):
            if (type(v) is not float and type(v) is not int) or not math.isfinite(v):
                raise _fail(f"{path}face[{i}]", "a finite number", v)
        face = tuple(float(v) for v in values)
    return Detection(
        x=_float(obj, "x", path, -MAX_COORD_M, MAX_COORD_M),
        y=_float(obj, "y", path, -MAX_COORD_M, MAX_COORD_M),
        z=_float(obj, "z", path, -MAX_COORD_M, MAX_COORD_M),
        height=_float(obj, "height", path, 0.0, 10.0),
        confidence=_float(obj, "confidence", path, 0.0, 1.0),
        distance=_float(obj, "distance", path, 0.0, MAX_COORD_M),
        bbox=bbox,
        appearance=appearance,
        face=face,
    )


def decode_detection_batch(payload: bytes | bytearray | memoryview | str) -> DetectionBatch:
    """Decode and validate wire bytes into a :class:`DetectionBatch`.

    Raises
    ------
    WireFormatError
        Naming the first field that is missing, of the wrong type, not finite, out of
        range or too large.
    """
    obj = _parse(payload, "detections", _DETECTION_BATCH_KEYS)
    items = _list(obj, "detections", "")
    return DetectionBatch(
        sensor_id=_name(obj, "sensor_id", ""),
        seq=_int(obj, "seq", ""),
        stamp=_float(obj, "stamp", "", 0.0, 1.0e11),
        frame_id=_name(obj, "frame_id", ""),
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
    {"v", "kind", "stamp", "seq", "frame_id", "tracks", "alive_ids", "max_id"}
)
_HEARTBEAT_KEYS = frozenset({"v", "kind", "stamp", "seq", "alive_ids", "max_id"})
_MAX_ID = (1 << 31) - 1  # OpenPTrack clients read ids as int32


def track_dict(t: Track) -> dict[str, Any]:
    """A track as the JSON object used on the wire (optional fields only when set).

    Raises
    ------
    WireFormatError
        If a number is NaN or infinite.
    """
    _check_finite(
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
    _check_finite("track batch", (batch.stamp,), "stamp")
    return _dumps(
        {
            "v": SCHEMA_VERSION,
            "kind": "tracks",
            "stamp": batch.stamp,
            "seq": batch.seq,
            "frame_id": batch.frame_id,
            "tracks": [track_dict(t) for t in batch.tracks],
            "alive_ids": list(batch.alive_ids),
            "max_id": batch.max_id,
        }
    )


def _decode_track(obj: Any, path: str) -> Track:
    _check_keys(obj, _TRACK_KEYS, path)
    confirmed = _bool(obj, "confirmed", path, default=True)
    stable_id = _int(obj, "stable_id", path, 0, _MAX_ID) if "stable_id" in obj else None
    identity = None
    if "identity" in obj:
        identity = obj["identity"]
        if type(identity) is not str or len(identity) > MAX_NAME_LEN:
            raise _fail(
                path + "identity", f"a string of at most {MAX_NAME_LEN} characters", identity
            )
    return Track(
        id=_int(obj, "id", path, 1, _MAX_ID),
        x=_float(obj, "x", path, -MAX_COORD_M, MAX_COORD_M),
        y=_float(obj, "y", path, -MAX_COORD_M, MAX_COORD_M),
        z=_float(obj, "z", path, -MAX_COORD_M, MAX_COORD_M),
        height=_float(obj, "height", path, 0.0, 10.0),
        vx=_float(obj, "vx", path, -1.0e3, 1.0e3),
        vy=_float(obj, "vy", path, -1.0e3, 1.0e3),
        age=_float(obj, "age", path, 0.0, 1.0e9),
        confidence=_float(obj, "confidence", path, 0.0, 1.0),
        visibility=Visibility(_int(obj, "visibility", path, 0, 2)),
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
    obj = _parse(payload, "tracks", _TRACK_BATCH_KEYS)
    items = _list(obj, "tracks", "")
    return TrackBatch(
        stamp=_float(obj, "stamp", "", 0.0, 1.0e11),
        seq=_int(obj, "seq", ""),
        frame_id=_name(obj, "frame_id", ""),
        tracks=tuple(_decode_track(t, f"tracks[{i}].") for i, t in enumerate(items)),
        alive_ids=_int_list(obj, "alive_ids", "", 1, _MAX_ID, MAX_ITEMS),
        max_id=_int(obj, "max_id", "", 0, _MAX_ID),
    )


def encode_heartbeat(heartbeat: Heartbeat) -> bytes:
    """Encode a :class:`Heartbeat` to wire bytes."""
    _check_finite("heartbeat", (heartbeat.stamp,), "stamp")
    return _dumps(
        {
            "v": SCHEMA_VERSION,
            "kind": "heartbeat",
            "stamp": heartbeat.stamp,
            "seq": heartbeat.seq,
            "alive_ids": list(heartbeat.alive_ids),
            "max_id": heartbeat.max_id,
        }
    )


def decode_heartbeat(payload: bytes | bytearray | memoryview | str) -> Heartbeat:
    """Decode and validate wire bytes into a :class:`Heartbeat`.

    Raises
    ------
    WireFormatError
        Naming the first invalid field.
    """
    obj = _parse(payload, "heartbeat", _HEARTBEAT_KEYS)
    return Heartbeat(
        stamp=_float(obj, "stamp", "", 0.0, 1.0e11),
        seq=_int(obj, "seq", ""),
        alive_ids=_int_list(obj, "alive_ids", "", 1, _MAX_ID, MAX_ITEMS),
        max_id=_int(obj, "max_id", "", 0, _MAX_ID),
    )


# ---------------------------------------------------------------------- ground truth

_PERSON_KEYS = frozenset({"id", "x", "y", "height", "vx", "vy", "kind", "covered"})
_GROUND_TRUTH_KEYS = frozenset({"v", "kind", "stamp", "seq", "people"})
_PERSON_KINDS = ("adult", "child")


def encode_ground_truth(frame: GroundTruthFrame) -> bytes:
    """Encode a :class:`GroundTruthFrame` to wire bytes."""
    _check_finite("ground truth", (frame.stamp,), "stamp")
    people = []
    for p in frame.people:
        _check_finite("person", (p.x, p.y, p.height, p.vx, p.vy), "x y height vx vy")
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
    return _dumps(
        {
            "v": SCHEMA_VERSION,
            "kind": "ground_truth",
            "stamp": frame.stamp,
            "seq": frame.seq,
            "people": people,
        }
    )


def _decode_person(obj: Any, path: str) -> PersonState:
    _check_keys(obj, _PERSON_KEYS, path)
    kind = obj.get("kind")
    if kind not in _PERSON_KINDS:
        raise _fail(path + "kind", " or ".join(map(repr, _PERSON_KINDS)), kind)
    covered = _bool(obj, "covered", path)
    return PersonState(
        id=_int(obj, "id", path),
        x=_float(obj, "x", path, -MAX_COORD_M, MAX_COORD_M),
        y=_float(obj, "y", path, -MAX_COORD_M, MAX_COORD_M),
        height=_float(obj, "height", path, 0.0, 10.0),
        vx=_float(obj, "vx", path, -1.0e3, 1.0e3),
        vy=_float(obj, "vy", path, -1.0e3, 1.0e3),
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
    obj = _parse(payload, "ground_truth", _GROUND_TRUTH_KEYS)
    items = _list(obj, "people", "")
    return GroundTruthFrame(
        stamp=_float(obj, "stamp", "", 0.0, 1.0e11),
        seq=_int(obj, "seq", ""),
        people=tuple(_decode_person(p, f"people[{i}].") for i, p in enumerate(items)),
    )


# ------------------------------------------------------------------------- node stats

_STATS_KEYS = frozenset(
    {"v", "kind", "node", "stamp", "uptime_s", "counters", "rates_hz", "timings_ms", "pid", "host"}
)


def encode_node_stats(stats: NodeStats) -> bytes:
    """Encode :class:`NodeStats` to wire bytes."""
    _check_finite("stats", (stats.stamp, stats.uptime_s), "stamp uptime_s")
    for group, values in (("rates_hz", stats.rates_hz), ("timings_ms", stats.timings_ms)):
        for name, value in values.items():
            if not math.isfinite(value):
                raise WireFormatError(f"cannot encode stats: {group}.{name} is {value}")
    return _dumps(
        {
            "v": SCHEMA_VERSION,
            "kind": "stats",
            "node": stats.node,
            "stamp": stats.stamp,
            "uptime_s": stats.uptime_s,
            "counters": stats.counters,
            "rates_hz": stats.rates_hz,
            "timings_ms": stats.timings_ms,
            "pid": stats.pid,
            "host": stats.host,
        }
    )


def _number_map(obj: dict, key: str, integer: bool) -> dict:
    value = obj.get(key)
    if type(value) is not dict or len(value) > 256:
        raise _fail(key, "an object of at most 256 entries", value)
    for name, v in value.items():
        ok = type(v) is int if integer else type(v) in (int, float) and math.isfinite(v)
        if not ok or len(name) > MAX_NAME_LEN:
            raise _fail(f"{key}.{name}", "an integer" if integer else "a finite number", v)
    return value


def decode_node_stats(payload: bytes | bytearray | memoryview | str) -> NodeStats:
    """Decode and validate wire bytes into :class:`NodeStats`.

    Raises
    ------
    WireFormatError
        Naming the first invalid field.
    """
    obj = _parse(payload, "stats", _STATS_KEYS)
    host = obj.get("host", "")
    if type(host) is not str or len(host) > 255:
        raise _fail("host", "a host name", host)
    return NodeStats(
        node=_name(obj, "node", ""),
        stamp=_float(obj, "stamp", "", 0.0, 1.0e11),
        uptime_s=_float(obj, "uptime_s", "", 0.0, 1.0e10),
        counters=_number_map(obj, "counters", integer=True),
        rates_hz={k: float(v) for k, v in _number_map(obj, "rates_hz", integer=False).items()},
        timings_ms={k: float(v) for k, v in _number_map(obj, "timings_ms", integer=False).items()},
        pid=_int(obj, "pid", ""),
        host=host,
    )


# ----------------------------------------------------------------- live configuration

_UPDATE_KEYS = frozenset({"v", "kind", "id", "set"})
_ACK_KEYS = frozenset({"v", "kind", "id", "node", "accepted", "error", "config"})
_MAX_PARAMS = 64
_SCALAR_TYPES = (bool, int, float, str, type(None))


def _request_id(obj: dict) -> str:
    value = obj.get("id")
    if type(value) is not str or not 0 < len(value) <= MAX_NAME_LEN:
        raise _fail("id", f"a string of 1-{MAX_NAME_LEN} characters", value)
    return value


def encode_config_update(update: ConfigUpdate) -> bytes:
    """Encode a :class:`ConfigUpdate` to wire bytes."""
    return _dumps(
        {"v": SCHEMA_VERSION, "kind": "config_update", "id": update.id, "set": update.set}
    )


def decode_config_update(payload: bytes | bytearray | memoryview | str) -> ConfigUpdate:
    """Decode and validate a :class:`ConfigUpdate`.

    Only the shape is checked here (names and plain JSON values); whether the values are
    allowed is for the node's own configuration model to say.

    Raises
    ------
    WireFormatError
        Naming the first invalid field.
    """
    obj = _parse(payload, "config_update", _UPDATE_KEYS)
    changes = obj.get("set", {})
    if type(changes) is not dict or len(changes) > _MAX_PARAMS:
        raise _fail("set", f"an object of at most {_MAX_PARAMS} parameters", changes)
    for name, value in changes.items():
        if not _NAME_RE.fullmatch(name) or len(name) > MAX_NAME_LEN:
            raise _fail(f"set.{name}", "a parameter name", name)
        if isinstance(value, float) and not math.isfinite(value):
            raise _fail(f"set.{name}", "a finite number", value)
        if not isinstance(value, _SCALAR_TYPES):
            raise _fail(f"set.{name}", "a number, string, boolean or null", value)
    return ConfigUpdate(id=_request_id(obj), set=changes)


def encode_config_ack(ack: ConfigAck) -> bytes:
    """Encode a :class:`ConfigAck` to wire bytes."""
    return _dumps(
        {
            "v": SCHEMA_VERSION,
            "kind": "config_ack",
            "id": ack.id,
            "node": ack.node,
            "accepted": ack.accepted,
            "error": ack.error,
            "config": ack.config,
        }
    )


def decode_config_ack(payload: bytes | bytearray | memoryview | str) -> ConfigAck:
    """Decode and validate a :class:`ConfigAck`.

    Raises
    ------
    WireFormatError
        Naming the first invalid field.
    """
    obj = _parse(payload, "config_ack", _ACK_KEYS)
    accepted = _bool(obj, "accepted", "")
    error = obj.get("error", "")
    if type(error) is not str or len(error) > 4096:
        raise _fail("error", "a string of at most 4096 characters", error)
    config = obj.get("config", {})
    if type(config) is not dict:
        raise _fail("config", "an object", config)
    return ConfigAck(
        id=_request_id(obj),
        node=_name(obj, "node", ""),
        accepted=accepted,
        error=error,
        config=config,
    )
