"""``openptrack status``: the live nodes of a site and their message rates."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

import orjson

from openptrack_py.cli.common import start_logging
from openptrack_py.runtime.args import add_common_arguments, bus_from_args, network_from_args

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers


def add_parser(subparsers: Subparsers) -> None:
    """Register ``status``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
        "status",
        help="list live nodes and their message rates",
        description="List the nodes of a site that are alive (Zenoh liveliness) with the "
        "rates from their latest stats.",
    )
    add_common_arguments(p)
    p.add_argument("--wait", type=float, default=2.5, help="seconds to listen before printing")
    p.add_argument("--watch", action="store_true", help="keep printing until Ctrl-C")
    p.add_argument("--format", choices=("table", "json"), default="table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print the live nodes once (status 1 if none) or, with ``--watch``, until Ctrl-C."""
    from openptrack_py.eval.runner import format_table
    from openptrack_py.runtime.status import StatusBoard
    from openptrack_py.runtime.stop import stop_on_signals

    start_logging(args)
    cfg = network_from_args(args)
    with bus_from_args(cfg, args) as bus, stop_on_signals() as stop:
        board = StatusBoard(bus, cfg.site)
        try:
            while not stop.wait(args.wait):
                rows = board.rows()
                if args.format == "json":
                    print(orjson.dumps(rows).decode(), flush=True)
                else:
                    columns = ["node", "alive", "host", "pid", "uptime_s", "in_hz", "out_hz"]
                    columns += ["dropped", "malformed", "stats_age_s"]
                    text = format_table(rows, columns) if rows else "no live nodes"
                    print(f"site {cfg.site!r}:\n{text}", flush=True)
                if not args.watch:
                    return 0 if rows else 1
            return 0
        finally:
            board.close()
