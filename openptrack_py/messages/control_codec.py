"""Builders and strict parsers for the control messages: heartbeat, node stats, config.

The heartbeat says which track ids are alive; node stats report a node's counters, rates
and timings; a config update asks a node to change parameters and the ack answers it.
One encoder and one decoder per kind, on the envelope and field readers of
:mod:`openptrack_py.messages.fields`; decoders raise
:class:`~openptrack_py.errors.WireFormatError` naming the first field that is wrong.
"""

from __future__ import annotations

import math

from openptrack_py.errors import WireFormatError
from openptrack_py.messages.config_update import ConfigAck, ConfigUpdate
from openptrack_py.messages.fields import (
    MAX_ID,
    MAX_ITEMS,
    MAX_NAME_LEN,
    NAME_RE,
    SCHEMA_VERSION,
    check_finite,
    dump_message,
    fail,
    parse_message,
    read_bool,
    read_float,
    read_int,
    read_int_list,
    read_name,
)
from openptrack_py.messages.stats import NodeStats
from openptrack_py.messages.track import Heartbeat

# ------------------------------------------------------------------------- heartbeat

_HEARTBEAT_KEYS = frozenset({"v", "kind", "stamp", "seq", "alive_ids", "max_id"})


def encode_heartbeat(heartbeat: Heartbeat) -> bytes:
    """Encode a :class:`Heartbeat` to wire bytes."""
    check_finite("heartbeat", (heartbeat.stamp,), "stamp")
    return dump_message(
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
    obj = parse_message(payload, "heartbeat", _HEARTBEAT_KEYS)
    return Heartbeat(
        stamp=read_float(obj, "stamp", "", 0.0, 1.0e11),
        seq=read_int(obj, "seq", ""),
        alive_ids=read_int_list(obj, "alive_ids", "", 1, MAX_ID, MAX_ITEMS),
        max_id=read_int(obj, "max_id", "", 0, MAX_ID),
    )


# ------------------------------------------------------------------------- node stats

_STATS_KEYS = frozenset(
    {"v", "kind", "node", "stamp", "uptime_s", "counters", "rates_hz", "timings_ms", "pid", "host"}
)


def encode_node_stats(stats: NodeStats) -> bytes:
    """Encode :class:`NodeStats` to wire bytes."""
    check_finite("stats", (stats.stamp, stats.uptime_s), "stamp uptime_s")
    for group, values in (("rates_hz", stats.rates_hz), ("timings_ms", stats.timings_ms)):
        for name, value in values.items():
            if not math.isfinite(value):
                raise WireFormatError(f"cannot encode stats: {group}.{name} is {value}")
    return dump_message(
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
        raise fail(key, "an object of at most 256 entries", value)
    for name, v in value.items():
        ok = type(v) is int if integer else type(v) in (int, float) and math.isfinite(v)
        if not ok or len(name) > MAX_NAME_LEN:
            raise fail(f"{key}.{name}", "an integer" if integer else "a finite number", v)
    return value


def decode_node_stats(payload: bytes | bytearray | memoryview | str) -> NodeStats:
    """Decode and validate wire bytes into :class:`NodeStats`.

    Raises
    ------
    WireFormatError
        Naming the first invalid field.
    """
    obj = parse_message(payload, "stats", _STATS_KEYS)
    host = obj.get("host", "")
    if type(host) is not str or len(host) > 255:
        raise fail("host", "a host name", host)
    return NodeStats(
        node=read_name(obj, "node", ""),
        stamp=read_float(obj, "stamp", "", 0.0, 1.0e11),
        uptime_s=read_float(obj, "uptime_s", "", 0.0, 1.0e10),
        counters=_number_map(obj, "counters", integer=True),
        rates_hz={k: float(v) for k, v in _number_map(obj, "rates_hz", integer=False).items()},
        timings_ms={k: float(v) for k, v in _number_map(obj, "timings_ms", integer=False).items()},
        pid=read_int(obj, "pid", ""),
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
        raise fail("id", f"a string of 1-{MAX_NAME_LEN} characters", value)
    return value


def encode_config_update(update: ConfigUpdate) -> bytes:
    """Encode a :class:`ConfigUpdate` to wire bytes."""
    return dump_message(
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
    obj = parse_message(payload, "config_update", _UPDATE_KEYS)
    changes = obj.get("set", {})
    if type(changes) is not dict or len(changes) > _MAX_PARAMS:
        raise fail("set", f"an object of at most {_MAX_PARAMS} parameters", changes)
    for name, value in changes.items():
        if not NAME_RE.fullmatch(name) or len(name) > MAX_NAME_LEN:
            raise fail(f"set.{name}", "a parameter name", name)
        if isinstance(value, float) and not math.isfinite(value):
            raise fail(f"set.{name}", "a finite number", value)
        if not isinstance(value, _SCALAR_TYPES):
            raise fail(f"set.{name}", "a number, string, boolean or null", value)
    return ConfigUpdate(id=_request_id(obj), set=changes)


def encode_config_ack(ack: ConfigAck) -> bytes:
    """Encode a :class:`ConfigAck` to wire bytes."""
    return dump_message(
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
    obj = parse_message(payload, "config_ack", _ACK_KEYS)
    accepted = read_bool(obj, "accepted", "")
    error = obj.get("error", "")
    if type(error) is not str or len(error) > 4096:
        raise fail("error", "a string of at most 4096 characters", error)
    config = obj.get("config", {})
    if type(config) is not dict:
        raise fail("config", "an object", config)
    return ConfigAck(
        id=_request_id(obj),
        node=read_name(obj, "node", ""),
        accepted=accepted,
        error=error,
        config=config,
    )
