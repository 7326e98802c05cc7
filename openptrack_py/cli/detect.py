"""``openptrack detect``: run the people detector on a cloud, folder, recording or device."""

from __future__ import annotations

import argparse
import json
import sys
from typing import TYPE_CHECKING, Any

from openptrack_py.cli.common import EXIT_CONFIG, add_detector_options, detector_config
from openptrack_py.errors import ConfigError

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers
    from openptrack_py.detection.frame import Frame
    from openptrack_py.detection.pipeline import DetectionResult
    from openptrack_py.sim.depth_source import SimDepthSource


def add_parser(subparsers: Subparsers) -> None:
    """Register ``detect``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
        "detect",
        help="detect people in a cloud file, a folder, a recording or a device",
        description="Run the people detector on INPUT and print, per frame, the ground plane "
        "it used and each detection's position (world frame with a pose, else a floor-aligned "
        "frame under the sensor: x forward, y left, z up), its position in the camera's "
        "optical frame (x right, y down, z forward), height, confidence and distance. INPUT is "
        "a .pcd/.ply cloud (organised or not, camera optical frame), a folder (recorded, TUM "
        "RGB-D, depth PNGs), a RealSense .bag, realsense[:SERIAL], azure-kinect[:N], or "
        "sim:SCENARIO[:SENSOR] (rendered simulation).",
    )
    p.add_argument("input", help="cloud file, folder, .bag, device or sim:SCENARIO[:SENSOR]")
    add_detector_options(p)
    p.add_argument("--ground", help="'auto' (estimate the floor) or a plane a,b,c,d")
    p.add_argument("--sensor-type", default=None, help="kinect1|kinect2|realsense|sr4500")
    p.add_argument("--frames", type=int, metavar="N", help="stop after N frames")
    p.add_argument(
        "--pose-from-sim", action="store_true", help="sim inputs: report in the world frame"
    )
    p.add_argument("--format", choices=("json", "table"), default="table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Detect people frame by frame: a JSON line per frame, or one table at the end."""
    from openptrack_py.detection.pipeline import PeopleDetector
    from openptrack_py.detection.sources import open_source
    from openptrack_py.errors import SourceError
    from openptrack_py.eval.runner import format_table

    try:
        config = detector_config(args)
        source = open_source(args.input, extra={"sim": sim_source})
    except (ConfigError, SourceError) as exc:
        print(f"openptrack detect: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    pose = None
    spec = getattr(source, "spec", None)
    if args.pose_from_sim and spec is not None:
        from openptrack_py.geometry import world_from_optical

        pose = world_from_optical(spec.pose)
    sensor_type = args.sensor_type or (spec.type.name if spec is not None else None)
    detector = PeopleDetector(
        config, world_from_camera=pose, sensor_type=sensor_type, frame_id="sensor"
    )
    rows = []
    frames = 0
    try:
        for frame in source.frames():
            result = detector.detect(frame)
            frames += 1
            record = _record(frame, result)
            if args.format == "json":
                print(json.dumps(record), flush=True)
            else:
                rows += _table_rows(record)
            if args.frames is not None and frames >= args.frames:
                break
    except SourceError as exc:
        print(f"openptrack detect: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    finally:
        source.close()
    if args.format == "table":
        columns = ["frame", "n", "x", "y", "z", "sensor_x", "sensor_y", "sensor_z", "height"]
        columns += ["conf", "frame_id", "ground"]
        print(format_table(rows, columns) if rows else f"no detections in {frames} frame(s)")
    return 0


def sim_source(spec: str) -> SimDepthSource:
    """``sim:SCENARIO[:SENSOR]``: a scenario's sensor rendered faster than real time."""
    from openptrack_py.sim.depth_source import SimDepthSource
    from openptrack_py.sim.scenarios import build_scenario
    from openptrack_py.sim.simulator import DEFAULT_START_TIME

    _, _, rest = spec.partition(":")
    name, _, sensor = rest.partition(":")
    scenario = build_scenario(name or "crowd")
    sensor = sensor or scenario.sensors[0].id
    return SimDepthSource(scenario, sensor, start_time=DEFAULT_START_TIME, realtime=False)


def _record(frame: Frame, result: DetectionResult) -> dict[str, Any]:
    """One frame's JSON line: its ground plane and detections, rounded for reading."""
    ground = [round(v, 5) for v in result.ground.coefficients] if result.ground else None
    return {
        "frame": frame.seq,
        "stamp": frame.stamp,
        "status": result.status,
        "frame_id": result.frame_id,
        "ground": ground,
        "ground_source": result.ground.source if result.ground else None,
        "detections": [
            {
                "position": [round(v, 4) for v in d.position],
                "sensor_position": [round(v, 4) for v in d.sensor_position],
                "height": round(d.height, 4),
                "confidence": round(d.confidence, 4),
                "distance": round(d.distance, 4),
                "bbox": list(d.bbox),
                "points": d.points,
            }
            for d in result.detections
        ],
    }


def _table_rows(record: dict[str, Any]) -> list[dict[str, Any]]:
    """One table row per detection of a frame's record."""
    rows = []
    for i, d in enumerate(record["detections"]):
        x, y, z = d["position"]
        sx, sy, sz = d["sensor_position"]
        rows.append(
            {
                "frame": record["frame"], "n": i, "x": x, "y": y, "z": z,
                "sensor_x": sx, "sensor_y": sy, "sensor_z": sz,
                "height": d["height"], "conf": d["confidence"],
                "frame_id": record["frame_id"], "ground": record["ground"],
            }
        )  # fmt: skip
    return rows
