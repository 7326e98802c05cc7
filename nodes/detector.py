"""Detector node: people detection on one sensor's depth frames.

Reads the sensor's frames (a camera, a recording, or — with ``sim.sensor_model: rgbd`` —
the simulator's rendering of that sensor), detects people and publishes a DetectionBatch
on ``opt/<site>/detections/<sensor_id>`` at the sensor's rate, dropping the oldest frames
when it falls behind. The sensor's pose and clock offset come from its calibration entry
(the file, or the master's ``calibration`` node when the file is not on this machine),
so do its intrinsics when the entry has them, and calibration updates published on
``opt/<site>/calibration/<sensor_id>`` apply live.

Typical usage::

    openptrack node detector -c site.yaml --sensor k2_a
    openptrack node detector -c site.yaml --sensor k2_a --input recordings/k2_a
    openptrack node detector -c demo --sensor k2_a --set sim.sensor_model=rgbd
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from openptrack_py.calibration.files import SensorCalibration
from openptrack_py.calibration.service import CalibrationFollower, sensor_entry
from openptrack_py.config import NetworkConfig
from openptrack_py.detection.service import DetectorService, source_for_sensor
from openptrack_py.errors import CalibrationError, ConfigError, SourceError
from openptrack_py.runtime.entry import run_sensor_node, sensor_node_parser
from openptrack_py.runtime.node import Node
from openptrack_py.sim.depth_source import sim_source_for_sensor


def main_loop(cfg: NetworkConfig, node: Node, args: argparse.Namespace) -> None:
    """Detect until the source ends or the node is stopped."""
    sensor = cfg.sensor(args.sensor)
    try:
        entry = sensor_entry(cfg, sensor.id, node.bus, node.keys)
    except CalibrationError as exc:
        raise ConfigError(str(exc)) from None
    try:
        source = source_for_sensor(cfg, sensor, args.input, sim_source_for_sensor)
    except SourceError as exc:
        raise ConfigError(f"sensors.{sensor.id}: {exc}") from None
    calibration = None if entry is None else (entry.world_from_optical(), entry.clock_offset_s)
    intrinsics = None if entry is None else entry.camera()
    service = DetectorService(node, sensor, cfg.detector, source, calibration, intrinsics)

    def apply(update: SensorCalibration) -> None:
        service.apply_calibration(
            update.world_from_optical(), update.clock_offset_s, update.camera()
        )

    follower = CalibrationFollower(node, sensor.id, apply)
    try:
        service.run()
    finally:
        follower.close()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the detector node."""
    parser = sensor_node_parser(
        "openptrack node detector", "Detect people in a sensor's depth frames."
    )
    return run_sensor_node("detector", parser, main_loop, argv)


if __name__ == "__main__":
    sys.exit(main())
