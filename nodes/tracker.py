"""Tracker node: fuses every sensor's detections into tracks on the ground plane.

Subscribes to ``opt/<site>/detections/*``, publishes a TrackBatch on
``opt/<site>/tracks`` after every step, and takes live parameter updates on
``opt/<site>/config/tracker`` (``openptrack config tracker key=value``).

Typical usage::

    openptrack node tracker -c demo
    openptrack node tracker -c demo --set tracker.gate_probability=0.99
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from openptrack_py.config import NetworkConfig, TrackerConfig
from openptrack_py.runtime.entry import node_parser, run_node
from openptrack_py.runtime.node import Node
from openptrack_py.tracking.service import TrackerService


def main_loop(cfg: NetworkConfig, node: Node, args: argparse.Namespace) -> None:
    """Track until stopped."""
    TrackerService(node, cfg.tracker or TrackerConfig(), cfg).run()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the tracker node."""
    parser = node_parser("openptrack node tracker", "Track people from detection batches.")
    return run_node("tracker", parser, main_loop, argv)


if __name__ == "__main__":
    sys.exit(main())
