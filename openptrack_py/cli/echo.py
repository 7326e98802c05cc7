"""``openptrack echo``: print the messages on a key expression as JSON lines."""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING

import orjson

from openptrack_py.cli.common import start_logging
from openptrack_py.errors import WireFormatError
from openptrack_py.runtime.args import add_common_arguments, bus_from_args, network_from_args

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers


def add_parser(subparsers: Subparsers) -> None:
    """Register ``echo``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
        "echo",
        help="print the messages on a key expression as JSON lines",
        description="Print every message on KEYEXPR as a JSON line "
        '{"t": receive time, "key": ..., "msg": ...}. Invalid messages go to stderr.',
    )
    p.add_argument("keyexpr", help="key expression, e.g. 'opt/default/detections/**'")
    add_common_arguments(p)
    p.add_argument("-n", "--count", type=int, help="stop after N messages")
    p.add_argument("--duration", type=float, help="stop after S seconds")
    p.add_argument("--raw", action="store_true", help="do not validate messages")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print messages until ``--count``, ``--duration``, Ctrl-C or a closed pipe."""
    from openptrack_py.messages.by_key import decoder_for_key
    from openptrack_py.runtime.node import Inbox
    from openptrack_py.runtime.stop import stop_on_signals

    start_logging(args)
    cfg = network_from_args(args)
    inbox: Inbox[tuple[float, str, bytes]] = Inbox(100_000)
    with bus_from_args(cfg, args) as bus, stop_on_signals() as stop:
        sub = bus.subscribe(args.keyexpr, lambda s: inbox.push((time.time(), s.key, s.payload)))
        deadline = None if args.duration is None else time.monotonic() + args.duration
        printed = malformed = 0
        try:
            while (args.count is None or printed < args.count) and not stop.is_set():
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    break
                item = inbox.get(timeout=0.2 if left is None else min(0.2, left))
                if item is None:
                    continue
                received, key, payload = item
                decode = None if args.raw else decoder_for_key(key)
                if decode is not None:
                    try:
                        decode(payload)
                    except WireFormatError as exc:
                        malformed += 1
                        print(f"malformed message on {key}: {exc}", file=sys.stderr)
                        continue
                sys.stdout.write(orjson.dumps(_line(received, key, payload)).decode() + "\n")
                sys.stdout.flush()
                printed += 1
        except BrokenPipeError:
            pass
        finally:
            sub.close()
    return 0


def _line(received: float, key: str, payload: bytes) -> dict:
    """One output line: the message itself when it is JSON, else its size and first bytes."""
    try:
        body = orjson.loads(payload)
    except orjson.JSONDecodeError:
        body = {
            "bytes": len(payload),
            "text": payload[:200].decode("utf-8", "replace"),
        }
    return {"t": round(received, 6), "key": key, "msg": body}
