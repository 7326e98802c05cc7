"""``openptrack calibrate walk``: calibration (or refinement) from one person walking.

The body of :func:`openptrack_py.cli.calibrate.run_walk`: simulates a walk through the
network's room (one person, the network's noise profile), solves every sensor's floor
pose and clock offset (:func:`~openptrack_py.calibration.walk.calibrate_walk`) or refines
the current ones (:func:`~openptrack_py.calibration.walk.refine_walk`, accepted only if it
cuts the disagreement between sensors on held-out parts of the walk), prints per sensor
the error against the simulator's truth, and writes the result where asked.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from typing import Any

from openptrack_py.cli.common import EXIT_CONFIG, print_rows

REFUSED = 1
"""Exit status of a refinement that would not help (nothing written)."""


def walk(
    args: argparse.Namespace,
    network_of: Callable[[argparse.Namespace], Any],
    write: Callable[[argparse.Namespace, Any, dict], str | None],
    fail: Callable[[object], int],
) -> int:
    """Run ``calibrate walk`` with the parent command's network, writer and error helpers."""
    from openptrack_py.errors import CalibrationError, ConfigError

    if not args.sim:
        return fail(
            "walk: only --sim is available from the command line; on real sensors call "
            "openptrack_py.calibration.walk.calibrate_walk on recorded detections"
        )
    try:
        network = network_of(args)
        session, result, reference = _solve(network, args)
        if not result.accepted:
            print(f"openptrack calibrate: refinement refused: {result.note}", file=sys.stderr)
            return REFUSED
        entries = _entries(network, result)
        written = write(args, network, entries)
        if args.plot is not None:
            from openptrack_py.calibration.plots import plot_walk

            start = session.believed_poses if args.refine else result.solved_poses
            plot_walk(args.plot, session.tracks, start, result)
    except (CalibrationError, ConfigError, ValueError) as exc:
        print(f"openptrack calibrate: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    rows = _rows(session, result, reference)
    columns = ["sensor", "error_cm", "error_deg", "clock_error_ms", "residual_cm"]
    print_rows(rows, columns, args.format)
    print(
        f"disagreement between sensors {result.before.binned_m:.3f} m -> "
        f"{result.after.binned_m:.3f} m ({result.method})",
        file=sys.stderr,
    )
    if written:
        print(f"wrote {written}", file=sys.stderr)
    return 0


def _solve(network: Any, args: argparse.Namespace) -> tuple[Any, Any, str]:
    from openptrack_py.calibration.walk import Pose2D, calibrate_walk, refine_walk
    from openptrack_py.eval.walk import simulate_walk

    if network.sim is None:
        raise ValueError("--sim: the network file has no 'sim' section")
    simulated = [s for s in network.sensors if s.source == "sim" and s.pose is not None]
    if len(simulated) < 2:
        raise ValueError("--sim needs at least two simulated sensors with a pose")
    session = simulate_walk(
        network.sim.scenario, seed=args.seed, duration_s=args.seconds,
        profile=network.sim.profile, sensors=simulated,
    )  # fmt: skip
    reference = simulated[0].id
    if args.refine:
        result = refine_walk(session.tracks, session.believed_poses, frame="floor")
    else:
        # the world frame: where the network file places the first sensor
        result = calibrate_walk(
            session.tracks,
            reference=reference,
            reference_pose=Pose2D.from_pose(simulated[0].pose),
        )
    return session, result, reference


def _entries(network: Any, result: Any) -> dict:
    from openptrack_py.calibration.files import SensorCalibration
    from openptrack_py.geometry import world_from_optical

    entries = {}
    for sensor in network.sensors:
        if sensor.id not in result.poses or sensor.pose is None:
            continue
        pose = result.poses[sensor.id].to_pose(sensor.pose)  # height, tilt, roll kept
        entries[sensor.id] = SensorCalibration.from_transform(
            world_from_optical(pose),
            method=result.method,
            clock_offset_s=round(float(result.clock_offsets_s.get(sensor.id, 0.0)), 6),
            residuals={
                "residual_m": round(float(result.residual_m.get(sensor.id, math.nan)), 4),
                "disagreement_m": round(float(result.after.binned_m), 4),
            },
        )
    return entries


def _rows(session: Any, result: Any, reference: str) -> list[dict[str, Any]]:
    """Per sensor: pose and clock errors against the truth, relative to ``reference``.

    Relative, because a refinement keeps the world frame where the current calibration
    put the walk (its common shift is not an error between sensors).
    """
    import numpy as np

    offsets = session.relative_offsets(reference)
    est_ref = np.linalg.inv(result.poses[reference].as_matrix())
    true_ref = np.linalg.inv(session.true_poses[reference].as_matrix())
    clock_ref = result.clock_offsets_s.get(reference, 0.0)
    rows = []
    for sid, pose in result.poses.items():
        est = est_ref @ pose.as_matrix()
        truth = true_ref @ session.true_poses[sid].as_matrix()
        gap = np.linalg.inv(truth) @ est
        clock = result.clock_offsets_s.get(sid, 0.0) - clock_ref - offsets.get(sid, 0.0)
        rows.append(
            {
                "sensor": sid,
                "error_cm": round(100 * float(np.hypot(gap[0, 2], gap[1, 2])), 2),
                "error_deg": round(abs(math.degrees(math.atan2(gap[1, 0], gap[0, 0]))), 3),
                "clock_error_ms": round(1000 * clock, 1),
                "residual_cm": round(100 * float(result.residual_m.get(sid, math.nan)), 2),
            }
        )
    return rows
