"""Simulator node: plays the network file's scenario in real time.

Publishes every simulated sensor's batches on ``opt/<site>/detections/<sensor_id>`` and
the ground truth on ``opt/<site>/ground_truth``. With ``sim.sensor_model: rgbd`` only the
ground truth: one ``detector`` node per sensor renders it and runs the real detector.

Typical usage::

    openptrack node sim -c demo
    openptrack node sim -c demo --set sim.scenario=crowd --set sim.use_scenario_sensors=true
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from openptrack_py.config import NetworkConfig
from openptrack_py.runtime.entry import node_parser, run_node
from openptrack_py.runtime.node import Node
from openptrack_py.sim.live import LivePlayer, scenario_from_network


def main_loop(cfg: NetworkConfig, node: Node, args: argparse.Namespace) -> None:
    """Play the scenario until it ends or the node is stopped."""
    assert cfg.sim is not None  # scenario_from_network checks
    scenario = scenario_from_network(cfg)
    player = LivePlayer(
        scenario,
        node,
        speed=cfg.sim.speed,
        ground_truth_rate_hz=cfg.sim.ground_truth_rate_hz,
        publish_detections=cfg.sim.sensor_model == "detections",
        start_time=cfg.sim.start_time,
    )
    player.run()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the simulator node."""
    parser = node_parser("openptrack node sim", "Play a simulated scenario on Zenoh.")
    return run_node("sim", parser, main_loop, argv)


if __name__ == "__main__":
    sys.exit(main())
