"""The wire envelope and strict field readers shared by every message codec.

Every message is one compact JSON object (orjson) whose first two keys are the schema
version ``"v"`` and the message ``"kind"``. :func:`parse_message` checks the payload's
size before parsing, then the envelope and the set of keys; the ``read_*`` functions
check one field each (type, finiteness, range) and raise
:class:`~openptrack_py.errors.WireFormatError` naming it by its path in the message
(e.g. ``detections[3].confidence``). :func:`dump_message` and :func:`check_finite` are
the encoding side: a bad number never reaches the wire.
"""

from __future__ import annotations

import math
import re
from typing import Any

import orjson

from openptrack_py.errors import WireFormatError

SCHEMA_VERSION = 1
MAX_PAYLOAD_BYTES = 1 << 20
"""Payloads above 1 MiB are rejected before parsing."""
MAX_ITEMS = 2000
"""Largest number of detections, tracks or people in one message."""
MAX_APPEARANCE_BINS = 256
MAX_FACE_DIMS = 1024
MAX_COORD_M = 1.0e4
"""Positions beyond 10 km are not people in a room: rejected as corrupt."""
MAX_HEIGHT_M = 10.0
"""Largest height of a person (or of a detection's top) above the floor."""
MAX_STAMP_S = 1.0e11
"""Largest time stamp, UNIX seconds (year 5138): anything later is corrupt."""
MAX_NAME_LEN = 128
MAX_ID = (1 << 31) - 1
"""Largest track id: OpenPTrack clients read ids as int32."""
MAX_INT = (1 << 63) - 1
"""Largest plain integer field (sequence numbers, pids)."""

NAME_RE = re.compile(r"[A-Za-z0-9_.\-]+")
"""Characters allowed in sensor, frame, node and parameter names."""


def fail(path: str, expected: str, value: Any) -> WireFormatError:
    """Build the error for a field that holds the wrong value.

    Parameters
    ----------
    path : str
        The field's path in the message, e.g. ``tracks[0].x``.
    expected : str
        What the field should hold, in words.
    value : Any
        What it holds; shown with ``repr``, cut to 60 characters.

    Returns
    -------
    WireFormatError
        ``"<path>: expected <expected>, got <value>"``, for the caller to raise.
    """
    shown = repr(value)
    if len(shown) > 60:
        shown = shown[:57] + "..."
    return WireFormatError(f"{path}: expected {expected}, got {shown}")


def read_float(
    obj: dict, key: str, path: str, lo: float = -math.inf, hi: float = math.inf
) -> float:
    """Read a required number in ``[lo, hi]`` (ints accepted, NaN and infinities not).

    Raises
    ------
    WireFormatError
        If ``obj[key]`` is missing, not a number, not finite or out of range.
    """
    try:
        value = obj[key]
    except KeyError:
        raise WireFormatError(f"{path}{key}: missing") from None
    kind = type(value)
    if kind is not float and kind is not int:
        raise fail(path + key, "a number", value)
    value = float(value)
    if not lo <= value <= hi:  # also rejects NaN
        if math.isnan(value) or math.isinf(value):
            raise fail(path + key, "a finite number", value)
        raise fail(path + key, f"a number in [{lo:g}, {hi:g}]", value)
    return value


def read_int(obj: dict, key: str, path: str, lo: int = 0, hi: int = MAX_INT) -> int:
    """Read a required integer in ``[lo, hi]`` (booleans are not integers here).

    Raises
    ------
    WireFormatError
        If ``obj[key]`` is missing, not an integer or out of range.
    """
    try:
        value = obj[key]
    except KeyError:
        raise WireFormatError(f"{path}{key}: missing") from None
    if type(value) is not int:
        raise fail(path + key, "an integer", value)
    if not lo <= value <= hi:
        raise fail(path + key, f"an integer in [{lo}, {hi}]", value)
    return value


def read_bool(obj: dict, key: str, path: str, default: bool | None = None) -> bool:
    """Read a boolean; ``default`` when the key is absent (``None``: it is required).

    Raises
    ------
    WireFormatError
        If the value (or the missing key without a default) is not ``true``/``false``.
    """
    value = obj.get(key, default)
    if type(value) is not bool:
        raise fail(path + key, "true or false", value)
    return value


def read_name(obj: dict, key: str, path: str) -> str:
    """Read a required name: 1 to :data:`MAX_NAME_LEN` characters from ``[A-Za-z0-9_.-]``.

    Raises
    ------
    WireFormatError
        If ``obj[key]`` is missing or not such a name.
    """
    try:
        value = obj[key]
    except KeyError:
        raise WireFormatError(f"{path}{key}: missing") from None
    if (
        type(value) is not str
        or not 0 < len(value) <= MAX_NAME_LEN
        or not NAME_RE.fullmatch(value)
    ):
        raise fail(path + key, f"a name of 1-{MAX_NAME_LEN} characters from [A-Za-z0-9_.-]", value)
    return value


def read_list(obj: dict, key: str, path: str, max_len: int = MAX_ITEMS) -> list:
    """Read a required array of at most ``max_len`` items (the items are not checked).

    Raises
    ------
    WireFormatError
        If ``obj[key]`` is missing, not an array or too long.
    """
    try:
        value = obj[key]
    except KeyError:
        raise WireFormatError(f"{path}{key}: missing") from None
    if type(value) is not list:
        raise fail(path + key, "an array", value)
    if len(value) > max_len:
        raise WireFormatError(f"{path}{key}: at most {max_len} items allowed, got {len(value)}")
    return value


def read_int_list(
    obj: dict, key: str, path: str, lo: int, hi: int, max_len: int
) -> tuple[int, ...]:
    """Read a required array of at most ``max_len`` integers, each in ``[lo, hi]``.

    Raises
    ------
    WireFormatError
        Naming the array, or the first item that is wrong (``<key>[<index>]``).
    """
    items = read_list(obj, key, path, max_len)
    # Fast path first (bool is an int subclass, hence the exact type test).
    exact_ints = all(type(v) is int for v in items)
    if exact_ints and (not items or (lo <= min(items) and max(items) <= hi)):
        return tuple(items)
    for i, v in enumerate(items):
        if type(v) is not int or not lo <= v <= hi:
            raise fail(f"{path}{key}[{i}]", f"an integer in [{lo}, {hi}]", v)
    raise AssertionError("unreachable")  # pragma: no cover


def check_keys(obj: Any, allowed: frozenset[str], path: str) -> None:
    """Check that ``obj`` is a JSON object with no keys outside ``allowed``.

    Raises
    ------
    WireFormatError
        If ``obj`` is not an object, or naming the first unknown key (sorted).
    """
    if type(obj) is not dict:
        raise fail(path.rstrip(".") or "message", "a JSON object", obj)
    extra = obj.keys() - allowed
    if extra:
        raise WireFormatError(
            f"{path}{sorted(extra)[0]}: unknown field (allowed: {', '.join(sorted(allowed))})"
        )


def parse_message(
    payload: bytes | bytearray | memoryview | str, kind: str, keys: frozenset[str]
) -> dict:
    """Parse wire bytes of one ``kind`` and check the envelope and the top-level keys.

    Parameters
    ----------
    payload : bytes, bytearray, memoryview or str
        The message; its size is checked before it is parsed.
    kind : str
        The ``"kind"`` the message must have.
    keys : frozenset of str
        Top-level keys allowed for that kind (``"v"`` and ``"kind"`` included).

    Returns
    -------
    dict
        The parsed object; its fields are for the caller to read.

    Raises
    ------
    WireFormatError
        If the payload is too large, not JSON, not an object, of another schema version
        or kind, or has an unknown key.
    """
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
        raise fail("message", "a JSON object", obj)
    version = obj.get("v")
    if version != SCHEMA_VERSION or type(version) is not int:
        raise fail("v", f"schema version {SCHEMA_VERSION}", version)
    if obj.get("kind") != kind:
        raise fail("kind", repr(kind), obj.get("kind"))
    check_keys(obj, keys, "")
    return obj


def dump_message(obj: dict) -> bytes:
    """Serialise a message object to compact JSON bytes.

    Raises
    ------
    WireFormatError
        If orjson cannot encode a value.
    """
    try:
        return orjson.dumps(obj)
    except (TypeError, orjson.JSONEncodeError) as exc:
        raise WireFormatError(f"cannot encode {obj.get('kind')}: {exc}") from None


def check_finite(kind: str, values: tuple[float, ...], names: str) -> None:
    """Refuse to encode NaN or infinities, so that a bad number never reaches the wire.

    Parameters
    ----------
    kind : str
        The message or item being encoded, for the error.
    values : tuple of float
        The numbers to check.
    names : str
        Their names, separated by spaces, in the same order.

    Raises
    ------
    WireFormatError
        ``"cannot encode <kind>: <name> is <value>"`` for the first non-finite value.
    """
    for name, value in zip(names.split(), values, strict=True):
        if not math.isfinite(value):
            raise WireFormatError(f"cannot encode {kind}: {name} is {value}")
