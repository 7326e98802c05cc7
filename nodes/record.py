"""Recorder node: writes every valid message on the chosen keys to an MCAP or JSON-lines file.

An MCAP recording also keeps the network file (its ``network`` metadata), so
``openptrack retrack`` runs the tracker the site ran.

Typical usage::

    openptrack node record -c demo --set recorder.path=runs/today.mcap
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from openptrack_py.config import NetworkConfig, RecorderConfig
from openptrack_py.recorder import Recorder
from openptrack_py.runtime.entry import node_parser, run_node
from openptrack_py.runtime.node import Node


def main_loop(cfg: NetworkConfig, node: Node, args: argparse.Namespace) -> None:
    """Record until stopped."""
    rec_cfg = cfg.recorder or RecorderConfig()
    path = Path(args.output) if args.output else rec_cfg.path
    keys = args.key or [node.keys.relative(k) for k in rec_cfg.keys]
    metadata = {"network": {"json": cfg.model_dump_json()}}
    Recorder(node, path, keys, metadata).run()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the recorder node."""
    parser = node_parser(
        "openptrack node record", "Record messages to an MCAP or JSON-lines file."
    )
    parser.add_argument("-o", "--output", help="output file (default: recorder.path)")
    parser.add_argument(
        "-k", "--key", action="append", help="full key expression to record (repeatable)"
    )
    return run_node("record", parser, main_loop, argv)


if __name__ == "__main__":
    sys.exit(main())
