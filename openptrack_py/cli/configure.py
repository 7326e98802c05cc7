"""``openptrack config``: change (or show) the live parameters of a running node.

Named ``configure`` so it is not confused with :mod:`openptrack_py.config`, the typed
configuration of network files.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING, Any

import orjson

from openptrack_py.cli.common import EXIT_CONFIG, start_logging
from openptrack_py.errors import WireFormatError
from openptrack_py.runtime.args import add_common_arguments, bus_from_args, network_from_args

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers
    from openptrack_py.messages.config_update import ConfigAck


def add_parser(subparsers: Subparsers) -> None:
    """Register ``config``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
        "config",
        help="change a running node's parameters (or show them)",
        description="Send a live parameter update to a running node, e.g. "
        "'openptrack config tracker gate_probability=0.99'. The node validates it, applies "
        "it between two steps and answers; without assignments the current parameters "
        "are printed. Exit status: 0 applied, 2 refused, 1 no answer.",
    )
    p.add_argument("node", help="node name, e.g. tracker")
    p.add_argument("assignments", nargs="*", metavar="KEY=VALUE", help="parameters to change")
    add_common_arguments(p)
    p.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for the node")
    p.add_argument("--format", choices=("text", "json"), default="text")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Send the update, wait for the node's answer and print it; return the exit status."""
    from openptrack_py.config import parse_override_value

    start_logging(args)
    changes = {}
    for item in args.assignments:
        key, sep, text = item.partition("=")
        if not sep or not key:
            print(f"openptrack config: {item!r}: expected key=value", file=sys.stderr)
            return EXIT_CONFIG
        changes[key.removeprefix(f"{args.node}.")] = parse_override_value(text)
    ack = ask_node(args, args.node, changes)
    if ack is None:
        return 1
    if args.format == "json":
        print(
            orjson.dumps(
                {"accepted": ack.accepted, "error": ack.error, "config": ack.config}
            ).decode()
        )
    elif not ack.accepted:
        pass
    elif changes:
        applied = " ".join(f"{k}={v}" for k, v in changes.items())
        print(f"{args.node}: applied {applied}")
    else:
        import yaml

        sys.stdout.write(yaml.safe_dump(ack.config, sort_keys=False))
    if not ack.accepted:
        print(f"openptrack config: {args.node} refused the update: {ack.error}", file=sys.stderr)
        return EXIT_CONFIG
    return 0


def ask_node(args: argparse.Namespace, node: str, changes: dict[str, Any]) -> ConfigAck | None:
    """Publish an update to ``node`` and return its answer (None, said on stderr, if none)."""
    import uuid

    from openptrack_py.messages.codec import decode_config_ack, encode_config_update
    from openptrack_py.messages.config_update import ConfigUpdate
    from openptrack_py.runtime.node import Inbox
    from openptrack_py.transport import SiteKeys, wait_for_subscribers

    cfg = network_from_args(args)
    keys = SiteKeys(cfg.site)
    request = ConfigUpdate(id=uuid.uuid4().hex[:16], set=changes)
    acks: Inbox[bytes] = Inbox(100)
    with bus_from_args(cfg, args) as bus:
        sub = bus.subscribe(keys.config_ack(node), lambda s: acks.push(s.payload))
        pub = bus.publisher(keys.config(node))
        if not wait_for_subscribers(pub, args.timeout):
            print(
                f"openptrack config: no node {node!r} listens on {keys.config(node)}",
                file=sys.stderr,
            )
            return None
        pub.put(encode_config_update(request))
        deadline = time.monotonic() + args.timeout
        ack = None
        while ack is None and time.monotonic() < deadline:
            payload = acks.get(timeout=0.1)
            if payload is None:
                continue
            try:
                candidate = decode_config_ack(payload)
            except WireFormatError:
                continue
            if candidate.id == request.id:
                ack = candidate
        sub.close()
        pub.close()
    if ack is None:
        print(
            f"openptrack config: {node!r} did not answer in {args.timeout:g} s",
            file=sys.stderr,
        )
    return ack
