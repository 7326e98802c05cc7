"""Encoders and strict decoders for every message that crosses a process.

Wire form: one compact JSON object (orjson) whose first two keys are the schema version
``"v"`` and the message ``"kind"``. Encoders omit optional fields that are ``None``.
Decoders check the size of the payload before parsing, then the type, finiteness and
range of every field, and raise :class:`~openptrack_py.errors.WireFormatError` naming the
first field that is wrong (e.g. ``detections[3].confidence``). They never return a
partially valid message.

This module is the one place to import them from. The code lives by role:
:mod:`~openptrack_py.messages.fields` (envelope, limits, field readers),
:mod:`~openptrack_py.messages.data_codec` (detections, tracks, ground truth) and
:mod:`~openptrack_py.messages.control_codec` (heartbeat, node stats, config update/ack).
"""

from __future__ import annotations

from openptrack_py.messages.control_codec import (
    decode_config_ack,
    decode_config_update,
    decode_heartbeat,
    decode_node_stats,
    encode_config_ack,
    encode_config_update,
    encode_heartbeat,
    encode_node_stats,
)
from openptrack_py.messages.data_codec import (
    decode_detection_batch,
    decode_ground_truth,
    decode_track_batch,
    encode_detection_batch,
    encode_ground_truth,
    encode_track_batch,
    track_dict,
)
from openptrack_py.messages.fields import (
    MAX_APPEARANCE_BINS,
    MAX_COORD_M,
    MAX_FACE_DIMS,
    MAX_ITEMS,
    MAX_NAME_LEN,
    MAX_PAYLOAD_BYTES,
    SCHEMA_VERSION,
)

__all__ = [
    "MAX_APPEARANCE_BINS",
    "MAX_COORD_M",
    "MAX_FACE_DIMS",
    "MAX_ITEMS",
    "MAX_NAME_LEN",
    "MAX_PAYLOAD_BYTES",
    "SCHEMA_VERSION",
    "decode_config_ack",
    "decode_config_update",
    "decode_detection_batch",
    "decode_ground_truth",
    "decode_heartbeat",
    "decode_node_stats",
    "decode_track_batch",
    "encode_config_ack",
    "encode_config_update",
    "encode_detection_batch",
    "encode_ground_truth",
    "encode_heartbeat",
    "encode_node_stats",
    "encode_track_batch",
    "track_dict",
]
