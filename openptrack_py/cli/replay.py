"""``openptrack replay``: put a recording back on the bus, at its pace or faster."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from openptrack_py.cli.common import EXIT_CONFIG, ProgressLine, bar, start_logging
from openptrack_py.runtime.args import add_common_arguments, bus_from_args, network_from_args

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers


def add_parser(subparsers: Subparsers) -> None:
    """Register ``replay``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
        "replay",
        help="put a recording back on the bus (no sensor needed)",
        description="Put a recording's messages back on this network's keys at the pace "
        "they were received (--speed to go faster), re-stamped to the replay's clock, so "
        "the tracker, the outputs and their clients run from it as from live sensors. By "
        "default the detections go out (a running tracker tracks them); --topics tracks "
        "feeds the outputs the recorded tracks instead. A damaged recording is replayed "
        "up to the damage, which is then named.",
    )
    add_common_arguments(p)
    p.add_argument("file", type=Path, help="the recording (.mcap or .jsonl)")
    p.add_argument("--speed", type=float, default=1.0, help="times real time (default 1)")
    p.add_argument("--loop", action="store_true", help="start again at the end, until Ctrl-C")
    p.add_argument(
        "--topics",
        default="detections",
        help="comma-separated topics to put: detections, tracks, ground_truth, stats",
    )
    p.add_argument("--keep-stamps", action="store_true", help="send the recorded times unchanged")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Replay; status 2 for a missing file or bad option, 0 otherwise."""
    from openptrack_py.recordings import SCHEMAS
    from openptrack_py.replayer import Replayer, ReplayProgress
    from openptrack_py.runtime.node import Node

    start_logging(args)
    if not args.file.is_file():
        print(f"openptrack replay: no file {args.file}", file=sys.stderr)
        return EXIT_CONFIG
    topics = [t.strip() for t in args.topics.split(",") if t.strip()]
    allowed = set(SCHEMAS) - {"config"}  # every recorded topic but configuration requests
    unknown = sorted(set(topics) - allowed)
    if unknown or not topics or not args.speed > 0:
        print(
            f"openptrack replay: --topics {args.topics!r} / --speed {args.speed}: topics "
            f"from {', '.join(sorted(allowed))}, speed > 0",
            file=sys.stderr,
        )
        return EXIT_CONFIG
    cfg = network_from_args(args)
    progress = ProgressLine()

    def show(p: ReplayProgress) -> None:
        where = bar(p.recorded_s / p.total_s) if p.total_s else f"{p.recorded_s:7.1f} s"
        progress.show(f"replay {args.file.name} {where} {p.messages} messages, pass {p.lap + 1}")

    with bus_from_args(cfg, args) as bus, Node("replay", bus, site=cfg.site) as node:
        node.install_signal_handlers()
        replayer = Replayer(
            node, args.file, speed=args.speed, loop=args.loop, topics=topics,
            restamp=not args.keep_stamps, on_progress=show,
        )  # fmt: skip
        put = replayer.run()
    progress.done()
    if replayer.stopped:
        print(f"openptrack replay: {replayer.stopped}", file=sys.stderr)
    print(f"replayed {put} messages from {args.file}")
    return 0
