#!/usr/bin/env python3
"""Print the tracks an OpenPTrack-compatible sender puts on UDP, one line per frame.

Reads what openptrack_py's UDP JSON sink sends (and what OpenPTrack v1/v2 sent): the
``people_tracks`` (opt-v2) or ``tracks`` (opt-v1) frames and the ``alive_IDs``
heartbeats, with or without the trailing NUL byte, zero padding, spaces after ``:``
and ``,``, and even OpenPTrack's bare ``nan`` numbers. A datagram that is not
readable is reported on stderr and skipped; the receiver never stops because of input.

Only the standard library is needed::

    python udp_receiver.py                      # 0.0.0.0:21234, until Ctrl-C
    python udp_receiver.py --count 100 --json   # 100 frames as JSON lines, then exit
    python udp_receiver.py --group 224.0.0.1    # join a multicast group first
"""

from __future__ import annotations

import argparse
import json
import math
import re
import socket
import struct
import sys
import time
from typing import Any

MAX_DATAGRAM = 65535
ROOT_KEYS = {"people_tracks": "opt-v2", "tracks": "opt-v1"}
# OpenPTrack's C++ writer prints non-finite numbers bare (nan, -nan, inf): not JSON.
_BARE_NON_FINITE = re.compile(r"(?<=[:\[,])\s*-?(?:nan|inf)\b", re.IGNORECASE)


def decode_objects(data: bytes) -> list[dict[str, Any]]:
    """The JSON objects in one datagram (normally exactly one).

    Everything from the first NUL byte on is ignored (OpenPTrack's trailing NUL, old
    zero padding). Several objects back to back (OpenPTrack v2's pose packing) are all
    returned.

    Raises
    ------
    ValueError
        If the datagram holds no readable JSON object.
    """
    text = data.split(b"\x00", 1)[0].decode("utf-8", errors="replace").strip()
    text = _BARE_NON_FINITE.sub("null", text)
    decoder = json.JSONDecoder()
    objects: list[dict[str, Any]] = []
    index = 0
    while index < len(text):
        obj, index = decoder.raw_decode(text, index)
        if not isinstance(obj, dict):
            raise ValueError(f"expected a JSON object, got {type(obj).__name__}")
        objects.append(obj)
        while index < len(text) and text[index].isspace():
            index += 1
    if not objects:
        raise ValueError("empty datagram")
    return objects


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(value) else None


def normalise(obj: dict[str, Any]) -> dict[str, Any] | None:
    """A decoded object as a flat record, or ``None`` if it is neither frame nor heartbeat.

    Frames give ``{"kind": "tracks", "format", "seq", "stamp", "frame_id", "tracks"}``,
    heartbeats ``{"kind": "heartbeat", "seq", "stamp", "alive_ids", "max_id"}``.
    """
    header = obj.get("header") if isinstance(obj.get("header"), dict) else {}
    stamp = header.get("stamp") if isinstance(header.get("stamp"), dict) else {}
    sec, nsec = _number(stamp.get("sec")), _number(stamp.get("nsec"))
    record: dict[str, Any] = {
        "seq": header.get("seq"),
        "stamp": sec + (nsec or 0.0) * 1e-9 if sec is not None else None,
        "frame_id": header.get("frame_id"),
    }
    if "alive_IDs" in obj:
        ids = obj.get("alive_IDs") if isinstance(obj.get("alive_IDs"), list) else []
        record.update(
            kind="heartbeat",
            alive_ids=[i for i in ids if isinstance(i, int)],
            max_id=obj.get("max_ID"),
        )
        return record
    for key, fmt in ROOT_KEYS.items():
        if isinstance(obj.get(key), list):
            tracks = []
            for item in obj[key]:
                if not isinstance(item, dict):
                    continue
                track = {"id": item.get("id")}
                for name in ("x", "y", "height", "age", "confidence"):
                    track[name] = _number(item.get(name))
                for name in ("stable_id", "face_name"):
                    if name in item:
                        track[name] = item[name]
                tracks.append(track)
            record.update(kind="tracks", format=fmt, tracks=tracks)
            return record
    return None


def _fmt(value: float | None) -> str:
    return "?" if value is None else f"{value:.2f}"


def describe(record: dict[str, Any]) -> str:
    """One human-readable line for a record."""
    if record["kind"] == "heartbeat":
        alive, max_id = record["alive_ids"], record["max_id"]
        return f"heartbeat seq={record['seq']} alive={alive} max_id={max_id}"
    people = " | ".join(
        f"{t['id']} ({_fmt(t['x'])}, {_fmt(t['y'])}) h={_fmt(t['height'])}"
        for t in record["tracks"]
    )
    line = f"seq={record['seq']} tracks={len(record['tracks'])}"
    return f"{line} | {people}" if people else line


def open_socket(host: str, port: int, group: str | None) -> socket.socket:
    """A UDP socket bound to ``host:port`` (and joined to ``group`` if given)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.bind((host, port))
    if group:
        membership = struct.pack("4s4s", socket.inet_aton(group), socket.inet_aton("0.0.0.0"))
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, membership)
    return sock


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--host", default="0.0.0.0", help="address to bind (default 0.0.0.0)")
    parser.add_argument("--port", type=int, default=21234, help="UDP port (default 21234)")
    parser.add_argument("--group", help="multicast group to join, e.g. 224.0.0.1")
    parser.add_argument("--count", type=int, default=0, help="exit after N frames (0: never)")
    parser.add_argument("--json", action="store_true", help="print each frame as a JSON line")
    parser.add_argument(
        "--no-heartbeats", dest="heartbeats", action="store_false", help="do not print heartbeats"
    )
    parser.add_argument(
        "--timeout", type=float, default=0.0, help="exit with code 1 after S s of silence"
    )
    args = parser.parse_args(argv)

    try:
        sock = open_socket(args.host, args.port, args.group)
    except OSError as exc:
        print(f"udp_receiver: cannot listen on {args.host}:{args.port}: {exc}", file=sys.stderr)
        return 2
    if args.timeout > 0:
        sock.settimeout(args.timeout)
    print(f"listening on {args.host}:{args.port}", file=sys.stderr, flush=True)
    frames = bad = 0
    last_complaint = 0.0
    try:
        while args.count <= 0 or frames < args.count:
            try:
                data, peer = sock.recvfrom(MAX_DATAGRAM)
            except TimeoutError:
                print(f"udp_receiver: nothing for {args.timeout:g} s", file=sys.stderr)
                return 1
            try:
                records = [normalise(obj) for obj in decode_objects(data)]
            except ValueError as exc:
                bad += 1
                if time.monotonic() - last_complaint > 1.0:  # at most one complaint a second
                    last_complaint = time.monotonic()
                    print(
                        f"udp_receiver: unreadable datagram from {peer[0]}:{peer[1]} "
                        f"({len(data)} bytes, {bad} so far): {exc}",
                        file=sys.stderr,
                    )
                continue
            for record in records:
                if record is None or (record["kind"] == "heartbeat" and not args.heartbeats):
                    continue
                print(json.dumps(record) if args.json else describe(record), flush=True)
                if record["kind"] == "tracks":
                    frames += 1
                    if 0 < args.count <= frames:
                        break
    except KeyboardInterrupt:
        pass
    finally:
        sock.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
