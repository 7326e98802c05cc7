"""``openptrack calibrate checkerboard --recordings``: the procedure on recorded sessions.

The body of the recorded path of :func:`openptrack_py.cli.calibrate.run_checkerboard`.
Each sensor's computer records the session while someone moves the board through the
room, holds it still at each placement for a second or two and ends by laying it flat on
the floor (``openptrack record-sensor SOURCE DIR/<sensor id>``); the recordings are
brought to one folder and read here in time order, all sensors at once, with the
progress shown as if live (who sees the board, views per pair, image coverage). Still
runs of the board become views (:mod:`~openptrack_py.calibration.capture`) and every
pose is solved jointly (:func:`~openptrack_py.calibration.extrinsics.calibrate_extrinsics`).
``--sim --record DIR`` writes a simulated session as such recordings.
"""

from __future__ import annotations

import argparse
import heapq
import math
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from openptrack_py.errors import CalibrationError

PROGRESS_EVERY_S = 0.5
"""Recorded time between two progress updates."""
SEEN_WITHIN_S = 0.25
"""A sensor sees the board now if it found it this recently."""


def board_from_arg(text: str) -> Any:
    """The board of ``--board ROWSxCOLSxSQUARE`` (e.g. ``5x6x0.12``)."""
    from openptrack_py.calibration.checkerboard import Checkerboard

    parts = text.lower().split("x")
    try:
        if len(parts) != 3:
            raise ValueError(text)
        rows, cols, square = int(parts[0]), int(parts[1]), float(parts[2])
    except ValueError:
        raise ValueError(
            f"--board: expected ROWSxCOLSxSQUARE such as 5x6x0.12, got {text!r}"
        ) from None
    return Checkerboard(rows=rows, cols=cols, square_m=square)


def sim_sensors(network: Any) -> list[Any]:
    """The network's simulated sensors with a pose (at least two)."""
    simulated = [s for s in network.sensors if s.source == "sim" and s.pose is not None]
    if len(simulated) < 2:
        raise ValueError("--sim needs at least two simulated sensors with a pose")
    return simulated


def record_sim(network: Any, args: argparse.Namespace) -> list[Path]:
    """Write the network's simulated session as one recording per sensor."""
    from openptrack_py.eval.checkerboard import SimSensor, record_board_session
    from openptrack_py.sim.board_session import board_session
    from openptrack_py.sim.live import scenario_from_network

    sensors = [SimSensor.from_config(s) for s in sim_sensors(network)]
    room = scenario_from_network(network, calibrated=False).room
    board = board_from_arg(args.board)
    session = board_session(
        board, room, [s.spec() for s in sensors], np.random.default_rng(args.seed),
        placements=args.placements,
    )  # fmt: skip
    folders = record_board_session(sensors, room, session, args.record, seed=args.seed + 1)
    return list(folders.values())


def from_recordings(network: Any, args: argparse.Namespace, progress_view: Callable) -> Any:
    """Calibrate from ``DIR/<sensor id>`` recordings; the ``ExtrinsicCalibration``."""
    from openptrack_py.calibration.capture import StillBoardViews
    from openptrack_py.calibration.extrinsics import calibrate_extrinsics
    from openptrack_py.calibration.files import believed_poses
    from openptrack_py.calibration.progress import CalibrationProgress
    from openptrack_py.detection.sources import open_source
    from openptrack_py.sensor_types import SENSOR_TYPES

    board = board_from_arg(args.board)
    folders = {s.id: args.recordings / s.id for s in network.sensors}
    missing = [f"{sid} ({path})" for sid, path in folders.items() if not path.is_dir()]
    if missing:
        raise CalibrationError(f"checkerboard: no recording for sensor {', '.join(missing)}")
    types = {s.id: s.type for s in network.sensors}
    sizes = {sid: (SENSOR_TYPES[t].width, SENSOR_TYPES[t].height) for sid, t in types.items()}
    progress = progress_view(CalibrationProgress(sizes))
    views = {sid: StillBoardViews(sid, types[sid], board) for sid in folders}
    sources = {sid: open_source(str(path)) for sid, path in folders.items()}
    observations = []
    latest: dict[str, tuple[float, Any]] = {}
    shown = -math.inf
    try:
        for stamp, sid, frame in _in_time_order(sources):
            done, view = views[sid].add(frame)
            if done is not None:
                observations.append(done)
            latest[sid] = (stamp, None if view is None else view.corners)
            if stamp - shown >= PROGRESS_EVERY_S:
                shown = stamp
                progress.update(stamp, _seen_now(latest, stamp, folders))
    finally:
        for source in sources.values():
            source.close()
    for collector in views.values():
        last = collector.flush()
        if last is not None:
            observations.append(last)
    if sys.stderr.isatty():
        print(file=sys.stderr)  # end the progress line
    intrinsics = {sid: v.intrinsics for sid, v in views.items()}
    unknown = [sid for sid, k in intrinsics.items() if k is None]
    if unknown:
        raise CalibrationError(
            f"checkerboard: the recording of {', '.join(unknown)} has no frames with intrinsics"
        )
    floor_stamp, reference_pose = None, None
    if args.floor_board == "last":
        if not observations:
            raise CalibrationError("checkerboard: the board was never found")
        floor_stamp = max(o.stamp for o in observations)
    else:
        first = network.sensors[0].id
        reference_pose = believed_poses(network).get(first)
        if reference_pose is None:
            raise CalibrationError(
                f"checkerboard: --floor-board none takes the world from {first}'s pose, "
                "and the network gives it none"
            )
    return calibrate_extrinsics(
        observations,
        intrinsics,  # type: ignore[arg-type]
        board.object_points(),
        reference=network.sensors[0].id,
        floor_stamp=floor_stamp,
        reference_world_from_camera=reference_pose,
    )


def _in_time_order(sources: dict[str, Any]) -> Iterator[tuple[float, str, Any]]:
    """Every sensor's frames merged by stamp."""

    def tagged(sid: str, source: Any) -> Iterator[tuple[float, str, Any]]:
        for frame in source.frames():
            yield frame.stamp, sid, frame

    streams = [tagged(sid, source) for sid, source in sources.items()]
    return heapq.merge(*streams, key=lambda item: (item[0], item[1]))


def _seen_now(
    latest: dict[str, tuple[float, Any]], stamp: float, sensors: dict[str, Path]
) -> dict[str, Any]:
    out = {}
    for sid in sensors:
        seen = latest.get(sid)
        fresh = seen is not None and stamp - seen[0] <= SEEN_WITHIN_S
        out[sid] = seen[1] if fresh else None  # type: ignore[index]
    return out


def rows(calibration: Any) -> tuple[list[dict[str, Any]], list[str]]:
    """Per sensor: views, reprojection RMS and the pose found."""
    report = calibration.report
    out = []
    for sid, pose in calibration.poses().items():
        out.append(
            {
                "sensor": sid,
                "views": report.views[sid],
                "rms_px": round(report.rms_px[sid], 3),
                "x": round(pose.x, 4),
                "y": round(pose.y, 4),
                "z": round(pose.z, 4),
                "yaw_deg": round(pose.yaw_deg, 3),
                "pitch_deg": round(pose.pitch_deg, 3),
                "roll_deg": round(pose.roll_deg, 3),
            }
        )
    columns = ["sensor", "views", "rms_px", "x", "y", "z", "yaw_deg", "pitch_deg", "roll_deg"]
    return out, columns
