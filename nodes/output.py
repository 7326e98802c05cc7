"""Output node: smoothed tracks to creative apps over UDP JSON, OSC, WebSocket and Zenoh.

Subscribes to ``opt/<site>/tracks``; sends each frame to every sink of its ``outputs``
entry (``--name`` picks the entry; the first one by default) and republishes it on
``opt/<site>/tracks/smoothed``.

Typical usage::

    openptrack node output -c demo
    openptrack node output -c demo --name stage --set outputs.stage.source=raw
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from openptrack_py.config import NetworkConfig, OutputConfig
from openptrack_py.output.service import OutputService
from openptrack_py.runtime.entry import node_parser, run_node
from openptrack_py.runtime.node import Node


def main_loop(cfg: NetworkConfig, node: Node, args: argparse.Namespace) -> None:
    """Serve until stopped."""
    default = cfg.outputs[0] if cfg.outputs else OutputConfig()
    OutputService(node, cfg.output(args.name) if args.name else default, cfg).run()


def main(argv: Sequence[str] | None = None) -> int:
    """Run an output node."""
    parser = node_parser("openptrack node output", "Send tracks to creative apps.")
    return run_node("output", parser, main_loop, argv)


if __name__ == "__main__":
    sys.exit(main())
