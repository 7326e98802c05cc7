"""JSON Schemas of the messages a recording holds, one per kind of key.

An MCAP recording stores every message as the JSON it crossed the network in
(``message_encoding: json``), each channel with one of these schemas
(``encoding: jsonschema``), so tools such as Foxglove open a recording and show its
fields without our code. The schemas describe the wire form that
:mod:`openptrack_py.messages.codec` writes; the codec's decoders remain the strict check.
"""

from __future__ import annotations

from typing import Any

import orjson

__all__ = ["SCHEMAS", "schema_bytes", "schema_for_key"]

_NUMBER = {"type": "number"}
_INT = {"type": "integer"}
_NAME = {"type": "string", "pattern": "^[A-Za-z0-9_.-]{1,128}$"}
_STAMP = {"type": "number", "description": "UNIX seconds"}


def _message(kind: str, title: str, props: dict[str, Any], required: list[str]) -> dict:
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": title,
        "type": "object",
        "properties": {"v": _INT, "kind": {"const": kind}, **props},
        "required": ["v", "kind", *required],
        "additionalProperties": False,
    }


def _object(props: dict[str, Any], required: list[str]) -> dict:
    return {"type": "object", "properties": props, "required": required}


_DETECTION = _object(
    {
        "x": _NUMBER, "y": _NUMBER, "z": _NUMBER, "height": _NUMBER,
        "confidence": {"type": "number", "minimum": 0, "maximum": 1},
        "distance": _NUMBER,
        "bbox": {"type": "array", "items": _NUMBER, "minItems": 4, "maxItems": 4},
        "appearance": {"type": "array", "items": _INT},
        "face": {"type": "array", "items": _NUMBER},
        "face_confidence": _NUMBER,
    },
    ["x", "y", "z", "height", "confidence", "distance"],
)  # fmt: skip
_TRACK = _object(
    {
        "id": _INT, "x": _NUMBER, "y": _NUMBER, "z": _NUMBER, "height": _NUMBER,
        "vx": _NUMBER, "vy": _NUMBER, "age": _NUMBER, "confidence": _NUMBER,
        "visibility": _INT, "confirmed": {"type": "boolean"}, "stable_id": _INT,
        "identity": {"type": "string"},
    },
    ["id", "x", "y", "z", "height", "vx", "vy", "age", "confidence", "visibility"],
)  # fmt: skip
_PERSON = _object(
    {
        "id": _INT, "x": _NUMBER, "y": _NUMBER, "height": _NUMBER, "vx": _NUMBER,
        "vy": _NUMBER, "kind": {"enum": ["adult", "child"]}, "covered": {"type": "boolean"},
    },
    ["id", "x", "y", "height", "vx", "vy", "kind"],
)  # fmt: skip
_IDS = {"type": "array", "items": _INT}

SCHEMAS: dict[str, dict] = {
    "detections": _message(
        "detections",
        "openptrack.DetectionBatch",
        {
            "sensor_id": _NAME,
            "seq": _INT,
            "stamp": _STAMP,
            "frame_id": _NAME,
            "detections": {"type": "array", "items": _DETECTION},
        },
        ["sensor_id", "seq", "stamp", "frame_id", "detections"],
    ),
    "tracks": _message(
        "tracks",
        "openptrack.TrackBatch",
        {
            "stamp": _STAMP,
            "seq": _INT,
            "frame_id": _NAME,
            "tracks": {"type": "array", "items": _TRACK},
            "alive_ids": _IDS,
            "max_id": _INT,
            "source": _object(
                {"sensor_id": _NAME, "seq": _INT, "stamp": _STAMP}, ["sensor_id", "seq", "stamp"]
            ),
        },
        ["stamp", "seq", "frame_id", "tracks", "alive_ids", "max_id"],
    ),
    "ground_truth": _message(
        "ground_truth",
        "openptrack.GroundTruth",
        {"stamp": _STAMP, "seq": _INT, "people": {"type": "array", "items": _PERSON}},
        ["stamp", "seq", "people"],
    ),
    "heartbeat": _message(
        "heartbeat",
        "openptrack.Heartbeat",
        {"stamp": _STAMP, "seq": _INT, "alive_ids": _IDS, "max_id": _INT},
        ["stamp", "seq", "alive_ids", "max_id"],
    ),
    "stats": _message(
        "stats",
        "openptrack.NodeStats",
        {
            "node": _NAME,
            "stamp": _STAMP,
            "uptime_s": _NUMBER,
            "pid": _INT,
            "host": {"type": "string"},
            "counters": {"type": "object", "additionalProperties": _INT},
            "rates_hz": {"type": "object", "additionalProperties": _NUMBER},
            "timings_ms": {"type": "object", "additionalProperties": _NUMBER},
        },
        ["node", "stamp", "counters"],
    ),
    "config": {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "openptrack.ConfigMessage",
        "description": "A configuration update, or a node's acknowledgement of one",
        "type": "object",
        "properties": {"v": _INT, "kind": {"enum": ["config_update", "config_ack"]}},
        "required": ["v", "kind"],
    },
    "calibration": {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "openptrack.SensorCalibration",
        "description": "One sensor's calibration entry, as the calibration node publishes it",
        "type": "object",
        "properties": {"sensor_id": _NAME, "frame": _NAME, "entry": {"type": "object"}},
        "required": ["sensor_id", "entry"],
    },
}
"""Schema of each topic (the key's chunk after ``opt/<site>/``)."""


def schema_for_key(key: str) -> tuple[str, dict] | None:
    """``(topic, schema)`` of the messages on ``key`` (``opt/<site>/<topic>/...``)."""
    chunks = key.split("/")
    if len(chunks) < 3 or chunks[0] != "opt" or chunks[2] not in SCHEMAS:
        return None
    return chunks[2], SCHEMAS[chunks[2]]


def schema_bytes(topic: str) -> bytes:
    """The schema of ``topic`` as the bytes an MCAP schema record holds."""
    return orjson.dumps(SCHEMAS[topic])
