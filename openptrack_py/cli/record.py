"""``openptrack record``: record a running site to an MCAP (or JSON-lines) file."""

from __future__ import annotations

import argparse
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

from openptrack_py.cli.common import EXIT_CONFIG, ProgressLine, start_logging
from openptrack_py.runtime.args import add_common_arguments, bus_from_args, network_from_args

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers


def add_parser(subparsers: Subparsers) -> None:
    """Register ``record``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
        "record",
        help="record a running site to an MCAP file",
        description="Record the site's messages (detections, tracks, ground truth, "
        "calibration entries, stats by default: the network's recorder.keys) until "
        "--duration or Ctrl-C. An .mcap file keeps each key's schema and the network file "
        "(for 'openptrack retrack'); .jsonl writes JSON lines.",
    )
    add_common_arguments(p)
    p.add_argument("-o", "--output", type=Path, help="file (default: the network's recorder.path)")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    p.add_argument(
        "-k", "--key", action="append", help="key below opt/<site>/ to record (repeatable)"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Record until ``--duration`` or Ctrl-C; print where to."""
    from openptrack_py.config import RecorderConfig
    from openptrack_py.errors import ConfigError
    from openptrack_py.recorder import Recorder
    from openptrack_py.runtime.node import Node
    from openptrack_py.runtime.stop import stop_on_signals

    start_logging(args)
    cfg = network_from_args(args)
    rec_cfg = cfg.recorder or RecorderConfig()
    path = args.output or rec_cfg.path
    with bus_from_args(cfg, args) as bus, Node("record", bus, site=cfg.site) as node:
        keys = [node.keys.relative(k) for k in (args.key or rec_cfg.keys)]
        try:
            recorder = Recorder(node, path, keys, {"network": {"json": cfg.model_dump_json()}})
        except ConfigError as exc:
            print(f"openptrack record: {exc}", file=sys.stderr)
            return EXIT_CONFIG
        worker = threading.Thread(target=recorder.run, name="recorder")
        worker.start()
        progress = ProgressLine()
        start = time.monotonic()
        try:
            with stop_on_signals() as stop:  # Ctrl-C or SIGTERM: what was written stays
                while worker.is_alive():
                    elapsed = time.monotonic() - start
                    if args.duration is not None and elapsed >= args.duration:
                        break
                    size = recorder.path.stat().st_size if recorder.path.exists() else 0
                    progress.show(
                        f"recording {recorder.path}: {elapsed:5.0f} s, "
                        f"{recorder.lines} messages, {size / 1e6:.1f} MB"
                    )
                    if stop.wait(0.5):
                        break
        finally:
            node.stop()
            worker.join()
            progress.done()
    print(f"recorded {recorder.lines} messages to {recorder.path}")
    return 0
