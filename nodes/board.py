"""Board node: what one sensor sees of the checkerboard during a calibration session.

Runs on the sensor's machine in place of its detector while someone moves
the board through the room (Munaro et al., OpenPTrack, §4). It finds the board in each
of the sensor's frames (colour, or infrared for time-of-flight sensors), follows the
runs of frames in which it is held still, and publishes a compact report per frame on
``opt/<site>/board/<sensor_id>``: the corners seen, each completed still view with the
sensor's intrinsics, and a last report when the source runs out. The images never leave
the machine. ``openptrack calibrate checkerboard NETWORK --live SECONDS`` on the master
gathers the reports and solves every pose. A simulated sensor (with no ``--input``)
renders its view of the network's scripted board session (``--seed``,
``--placements``, ``--speed``), the one ``calibrate checkerboard --sim`` runs. The node
runs under the detector's name, so a secured site's sensor certificate is the one it
uses: stop the detector for the session (two nodes of one name would share one
liveliness token and one stats key).

Typical usage::

    openptrack node board -c site.yaml --sensor k2_a
    openptrack node board -c site.yaml --sensor k2_a --input recordings/k2_a
    openptrack node board -c demo --sensor k2_a --speed 4      # a simulated sensor
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from openptrack_py.calibration.board_wire import encode_board_report
from openptrack_py.calibration.capture import StillBoardViews
from openptrack_py.calibration.checkerboard import Checkerboard
from openptrack_py.config import NetworkConfig, SensorConfig
from openptrack_py.detection.service import source_for_sensor
from openptrack_py.errors import ConfigError, SourceError
from openptrack_py.eval.board_stream import SimBoardSource
from openptrack_py.runtime.entry import run_sensor_node, sensor_node_parser
from openptrack_py.runtime.node import Node


def main_loop(cfg: NetworkConfig, node: Node, args: argparse.Namespace) -> None:
    """Report the board until the source ends or the node is stopped."""
    sensor = cfg.sensor(args.sensor)
    board = Checkerboard.parse(args.board)

    def rendered(network: NetworkConfig, simulated: SensorConfig) -> SimBoardSource:
        return SimBoardSource(network, simulated.id, board, seed=args.seed,
                              placements=args.placements, speed=args.speed)  # fmt: skip

    try:
        source = source_for_sensor(cfg, sensor, args.input, rendered)
    except SourceError as exc:
        raise ConfigError(f"sensors.{sensor.id}: {exc}") from None
    views = StillBoardViews(sensor.id, sensor.type, board)
    publisher = node.publisher(node.keys.board(sensor.id))
    node.log.info("board", extra={"fields": {"sensor": sensor.id, "source": source.name}})
    if not publisher.has_subscribers():  # a recording played to nobody would be lost
        node.log.info("waiting for 'openptrack calibrate checkerboard --live' to listen")
        while node.running and not publisher.has_subscribers():
            node.wait(0.2)
    stamp = 0.0
    try:
        for frame in source.frames():
            if not node.running:
                break
            stamp = frame.stamp
            report = views.report(frame)
            publisher.put(encode_board_report(report))
            node.counters.inc("frames")
            if report.corners is not None:
                node.counters.inc("seen")
            if report.view is not None:
                node.counters.inc("views")
        publisher.put(encode_board_report(views.end_report(stamp)))
    finally:
        source.close()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the board node."""
    parser = sensor_node_parser("openptrack node board", "Report what a sensor sees of the board.")
    parser.add_argument(
        "--board",
        default="5x6x0.12",
        metavar="ROWSxCOLSxSQUARE",
        help="inner corners and square side in metres (default OpenPTrack's 5x6x0.12)",
    )
    sim = parser.add_argument_group("a simulated sensor (no --input): the scripted session")
    sim.add_argument("--seed", type=int, default=0, help="session seed (the same for all)")
    sim.add_argument("--placements", type=int, default=30, help="board placements")
    sim.add_argument("--speed", type=float, default=1.0, help="times real time (0: no pacing)")
    return run_sensor_node("board", parser, main_loop, argv)


if __name__ == "__main__":
    sys.exit(main())
