"""Calibration node: serves the network's calibration to the sensors' machines.

Answers queries on ``opt/<site>/calibration/<sensor_id>`` with the sensor's entry of the
network's calibration files, and publishes an entry there when its file changes (a
refinement accepted with ``openptrack calibrate ... --apply``, or an edit). An invalid
file is refused and the running calibration kept. The launcher starts it on the
tracker's machine when the network names a calibration file.

Typical usage::

    openptrack node calibration -c site.yaml
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from openptrack_py.calibration.service import CalibrationServer
from openptrack_py.config import NetworkConfig
from openptrack_py.errors import CalibrationError, ConfigError
from openptrack_py.runtime.entry import node_parser, run_node
from openptrack_py.runtime.node import Node


def main_loop(cfg: NetworkConfig, node: Node, args: argparse.Namespace) -> None:
    """Serve until stopped."""
    try:
        server = CalibrationServer(node, cfg)
    except CalibrationError as exc:
        raise ConfigError(str(exc)) from None
    server.run()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the calibration node."""
    parser = node_parser("openptrack node calibration", "Serve the network's calibration.")
    return run_node("calibration", parser, main_loop, argv)


if __name__ == "__main__":
    sys.exit(main())
