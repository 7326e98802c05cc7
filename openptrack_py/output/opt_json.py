"""OpenPTrack's UDP JSON, byte for byte, and a parser for it.

Tracks message (``opt-v2``; ``opt-v1`` has the root key ``tracks``)::

    {"header":{"seq":123,"stamp":{"sec":1441244414,"nsec":266356327},"frame_id":"world"},
     "people_tracks":[{"id":170,"x":0.740519,"y":-3.21577,"height":1.01898,
                       "age":79.4518,"confidence":0.491777}]}

Heartbeat::

    {"header":{"seq":5694,"stamp":{"sec":...,"nsec":...},"frame_id":"heartbeat"},
     "alive_IDs":[59,60],"max_ID":60}

As OpenPTrack writes them: compact, keys in this order, ``header`` first and the tracks
array last, integers for ``seq``/``sec``/``nsec``/``id``, floats with six significant
digits (C++ ``ostream`` default, i.e. ``%g``), and one trailing NUL byte (optional here).
Unlike OpenPTrack, a number is never ``nan``/``inf`` and a datagram never holds two JSON
objects; a frame larger than the datagram limit is split into several complete messages
with the same header. In ``opt-v2``, tracks with a stable identity also carry
``stable_id`` and, for registered people, ``face_name`` (OpenPTrack v2's face mode).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence

from openptrack_py.errors import WireFormatError
from openptrack_py.messages.track import Track

FORMATS = {"opt-v2": "people_tracks", "opt-v1": "tracks"}
_NUL = b"\x00"


def number(value: float) -> str:
    """``value`` as OpenPTrack writes it: six significant digits, ``%g`` style.

    Raises
    ------
    WireFormatError
        For NaN or infinity (OpenPTrack would write invalid JSON).
    """
    if not math.isfinite(value):
        raise WireFormatError(f"OpenPTrack JSON: refusing to write {value}")
    return format(value, ".6g")


def _string(text: str) -> str:
    # Jzon escapes '/' as '\/'; JSON allows both, and clients decode both.
    return json.dumps(text, ensure_ascii=False).replace("/", "\\/")


def sec_nsec(stamp: float) -> tuple[int, int]:
    """``stamp`` (seconds) as ROS-style whole seconds and nanoseconds."""
    sec = math.floor(stamp)
    return sec, min(round((stamp - sec) * 1e9), 999_999_999)


def _header(seq: int, stamp: float, frame_id: str) -> str:
    sec, nsec = sec_nsec(stamp)
    return (
        f'{{"header":{{"seq":{int(seq)},"stamp":{{"sec":{sec},"nsec":{nsec}}},'
        f'"frame_id":{_string(frame_id)}}}'
    )


def _track(track: Track, extended: bool) -> str:
    text = (
        f'{{"id":{int(track.id)},"x":{number(track.x)},"y":{number(track.y)},'
        f'"height":{number(track.height)},"age":{number(track.age)},'
        f'"confidence":{number(track.confidence)}'
    )
    if extended and track.stable_id is not None:
        text += f',"stable_id":{int(track.stable_id)}'
        if track.identity is not None:
            text += f',"face_name":{_string(track.identity)}'
    return text + "}"


def encode_tracks(
    tracks: Sequence[Track],
    *,
    seq: int,
    stamp: float,
    fmt: str = "opt-v2",
    trailing_nul: bool = True,
    max_bytes: int = 65507,
    frame_id: str = "world",
) -> list[bytes]:
    """One tracks frame as datagrams (normally one; more if it exceeds ``max_bytes``).

    Raises
    ------
    ValueError
        For an unknown format, or a single track that cannot fit in ``max_bytes``.
    """
    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    head = f'{_header(seq, stamp, frame_id)},"{FORMATS[fmt]}":['.encode()
    tail = b"]}" + (_NUL if trailing_nul else b"")
    items = [_track(t, fmt == "opt-v2").encode() for t in tracks]
    out: list[bytes] = []
    chunk: list[bytes] = []
    size = len(head) + len(tail)
    for item in items:
        added = len(item) + (1 if chunk else 0)
        if chunk and size + added > max_bytes:
            out.append(head + b",".join(chunk) + tail)
            chunk, size = [], len(head) + len(tail)
            added = len(item)
        if size + added > max_bytes:
            raise ValueError(f"one track needs more than max_bytes={max_bytes} bytes")
        chunk.append(item)
        size += added
    out.append(head + b",".join(chunk) + tail)
    return out


def encode_opt_heartbeat(
    alive_ids: Iterable[int], max_id: int, *, seq: int, stamp: float, trailing_nul: bool = True
) -> bytes:
    """An OpenPTrack UDP heartbeat datagram (``alive_IDs`` / ``max_ID``).

    Not to be confused with :func:`openptrack_py.messages.codec.encode_heartbeat`, the
    tracker's internal Zenoh heartbeat message.

    Parameters
    ----------
    alive_ids : iterable of int
        Ids of the tracks alive now.
    max_id : int
        The largest id ever given out.
    seq, stamp : int, float
        Header sequence number and time (seconds).
    trailing_nul : bool
        End the datagram with one NUL byte, as OpenPTrack does.

    Returns
    -------
    bytes
        One datagram, however long ``alive_ids`` is (see :func:`encode_opt_heartbeats`).
    """
    ids = ",".join(str(int(i)) for i in alive_ids)
    data = f'{_header(seq, stamp, "heartbeat")},"alive_IDs":[{ids}],"max_ID":{int(max_id)}}}'
    return data.encode() + (_NUL if trailing_nul else b"")


def encode_opt_heartbeats(
    alive_ids: Sequence[int],
    max_id: int,
    *,
    seq: int,
    stamp: float,
    trailing_nul: bool = True,
    max_bytes: int = 65507,
) -> list[bytes]:
    """An OpenPTrack UDP heartbeat as datagrams of at most ``max_bytes``.

    Normally one; a very long ``alive_IDs`` list is split over several complete
    heartbeats with the same header, each listing part of the ids. Arguments as for
    :func:`encode_opt_heartbeat`.
    """
    ids = list(alive_ids)
    whole = encode_opt_heartbeat(ids, max_id, seq=seq, stamp=stamp, trailing_nul=trailing_nul)
    if len(whole) <= max_bytes or len(ids) <= 1:
        return [whole]
    half = len(ids) // 2
    return [
        *encode_opt_heartbeats(ids[:half], max_id, seq=seq, stamp=stamp,
                           trailing_nul=trailing_nul, max_bytes=max_bytes),
        *encode_opt_heartbeats(ids[half:], max_id, seq=seq, stamp=stamp,
                           trailing_nul=trailing_nul, max_bytes=max_bytes),
    ]  # fmt: skip


def parse_datagram(data: bytes) -> dict:
    """Decode one OpenPTrack datagram (trailing NULs allowed) into a dict.

    Raises
    ------
    WireFormatError
        If it is not exactly one JSON object with a header.
    """
    text = data.rstrip(_NUL)
    try:
        obj = json.loads(text)
    except (ValueError, UnicodeDecodeError) as exc:
        raise WireFormatError(f"OpenPTrack datagram: not one JSON object ({exc})") from None
    if not isinstance(obj, dict) or "header" not in obj:
        raise WireFormatError("OpenPTrack datagram: no header")
    return obj
