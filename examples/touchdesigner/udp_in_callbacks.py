"""Callbacks of a TouchDesigner UDP In DAT that receives openptrack_py's UDP JSON.

Set-up (see README.md): a UDP In DAT on port 21234 with *Row/Callback Format* set to
*One Per Message*, and this text as its *Callbacks DAT*; next to it a Table DAT named
``tracks`` (and, optionally, one named ``alive``). Each tracks frame replaces the
``tracks`` table with a header row ``id x y height age confidence`` and one row per
person; each heartbeat replaces the ``alive`` table with one id per row. Heartbeats,
unreadable datagrams and messages that are not tracks never raise: they leave the
``tracks`` table as it was.

The parsing is plain Python at module level (:func:`parse_message`,
:func:`parse_heartbeat`), so it can be tried and tested outside TouchDesigner.
"""

from __future__ import annotations

import json
import math

TRACKS_TABLE = "tracks"  # name of the Table DAT, next to the UDP In DAT
ALIVE_TABLE = "alive"  # optional
COLUMNS = ("id", "x", "y", "height", "age", "confidence")
ROOT_KEYS = ("people_tracks", "tracks")  # opt-v2, opt-v1


def _decode(data) -> dict | None:
    """One datagram as a JSON object, or ``None`` if it is not readable."""
    if isinstance(data, str):
        data = data.encode("utf-8", errors="replace")
    # Up to the first NUL: OpenPTrack ends each datagram with one (older versions padded
    # with many); openptrack_py can send it or not.
    text = bytes(data).split(b"\x00", 1)[0].decode("utf-8", errors="replace").strip()
    try:
        obj = json.loads(text)
    except ValueError:
        return None
    return obj if isinstance(obj, dict) else None


def _number(value, default: float = -1.0) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return default
    value = float(value)
    return value if math.isfinite(value) else default


def parse_message(data) -> list[dict] | None:
    """The tracks of one datagram, or ``None`` if it is not a tracks frame.

    Parameters
    ----------
    data : bytes, bytearray or str
        One UDP datagram (what the UDP In DAT passes as ``bytes``).

    Returns
    -------
    list of dict or None
        One dict per track with ``id`` (int) and ``x``, ``y``, ``height``, ``age``,
        ``confidence`` (float; -1 when missing), sorted by id. ``None`` for heartbeats
        and for anything unreadable. An empty list is an empty room.
    """
    obj = _decode(data)
    if obj is None:
        return None
    items = next((obj[k] for k in ROOT_KEYS if isinstance(obj.get(k), list)), None)
    if items is None:
        return None
    tracks = []
    for item in items:
        if not isinstance(item, dict):
            continue
        ident = item.get("id")
        if isinstance(ident, bool) or not isinstance(ident, (int, float)):
            continue
        track = {"id": int(ident)}
        for name in COLUMNS[1:]:
            track[name] = _number(item.get(name))
        tracks.append(track)
    tracks.sort(key=lambda t: t["id"])
    return tracks


def parse_heartbeat(data) -> list[int] | None:
    """The live track ids of a heartbeat datagram, or ``None`` if it is not one."""
    obj = _decode(data)
    if obj is None or not isinstance(obj.get("alive_IDs"), list):
        return None
    return [int(i) for i in obj["alive_IDs"] if isinstance(i, int) and not isinstance(i, bool)]


def table_rows(tracks: list[dict]) -> list[list]:
    """Rows for the ``tracks`` Table DAT: a header, then one row per track."""
    rows: list[list] = [list(COLUMNS)]
    for t in tracks:
        rows.append([t["id"]] + [round(t[name], 4) for name in COLUMNS[1:]])
    return rows


def _sibling(dat, name: str):
    parent = dat.parent()
    return parent.op(name) if parent is not None else None


# --------------------------------------------------------- TouchDesigner callbacks
# me - this DAT
# dat - the DAT that received a message
# rowIndex - the row number the message was placed into
# message - an ascii representation of the data
# bytes - a byte array of the message
# peer - a Peer object describing the originating message


def onReceive(dat, rowIndex, message, bytes, peer):  # noqa: N802, N803
    tracks = parse_message(bytes)
    if tracks is not None:
        table = _sibling(dat, TRACKS_TABLE)
        if table is not None:
            table.clear()
            for row in table_rows(tracks):
                table.appendRow(row)
        return
    alive = parse_heartbeat(bytes)
    if alive is not None:
        table = _sibling(dat, ALIVE_TABLE)
        if table is not None:
            table.clear()
            table.appendRow(["id"])
            for ident in alive:
                table.appendRow([ident])
    return
