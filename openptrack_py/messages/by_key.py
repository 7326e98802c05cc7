"""Which decoder applies to a key below ``opt/<site>/``."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from openptrack_py.messages.codec import (
    decode_config_ack,
    decode_config_update,
    decode_detection_batch,
    decode_ground_truth,
    decode_heartbeat,
    decode_node_stats,
    decode_track_batch,
)

_BY_TOPIC: dict[str, Callable[[bytes], Any]] = {
    "detections": decode_detection_batch,
    "tracks": decode_track_batch,
    "ground_truth": decode_ground_truth,
    "heartbeat": decode_heartbeat,
    "stats": decode_node_stats,
    "config": decode_config_update,
}

TOPICS = tuple(_BY_TOPIC)


def decoder_for_key(key: str) -> Callable[[bytes], Any] | None:
    """The decoder for messages on ``key`` (``opt/<site>/<topic>/...``), if known.

    Works on key expressions too, as long as the topic chunk is literal.
    """
    chunks = key.split("/")
    if len(chunks) < 3 or chunks[0] != "opt":
        return None
    if chunks[2] == "config" and chunks[-1] == "ack":
        return decode_config_ack
    return _BY_TOPIC.get(chunks[2])
