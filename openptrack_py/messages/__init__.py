"""Plain message types and their wire codecs. No I/O happens here."""

from openptrack_py.messages.codec import (
    SCHEMA_VERSION,
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
from openptrack_py.messages.detection import Detection, DetectionBatch
from openptrack_py.messages.ground_truth import GroundTruthFrame, PersonState
from openptrack_py.messages.stats import NodeStats
from openptrack_py.messages.track import Heartbeat, Track, TrackBatch, Visibility

__all__ = [
    "SCHEMA_VERSION",
    "ConfigAck",
    "ConfigUpdate",
    "Detection",
    "DetectionBatch",
    "GroundTruthFrame",
    "Heartbeat",
    "NodeStats",
    "PersonState",
    "Track",
    "TrackBatch",
    "Visibility",
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
]
