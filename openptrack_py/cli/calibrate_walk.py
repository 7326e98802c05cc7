"""``openptrack calibrate walk``: calibration (or refinement) from one person walking.

The body of :func:`openptrack_py.cli.calibrate.run_walk`. The walk comes from one of:

* ``--sim``: simulated through the network's room (one person, the network's noise
  profile); per sensor the error against the simulator's truth is printed;
* ``--detections FILE``: the detections recorded during a walk (``openptrack node
  record`` JSON lines, or the CSV / JSON-lines detections format of ``openptrack eval``),
  each sensor's in its own floor frame (a detector without a pose) or in the world
  through the pose the network gives it;
* ``--live SECONDS``: the running network's detections over Zenoh for that long, with
  each sensor's count of detections shown as they come.

It solves every sensor's floor pose and clock offset
(:func:`~openptrack_py.calibration.walk.calibrate_walk`; the world frame stays where the
network places its first sensor) or refines the current ones
(:func:`~openptrack_py.calibration.walk.refine_walk`, accepted only if it cuts the
disagreement between sensors on held-out parts of the walk), and writes the result
where asked. A sensor keeps the height, tilt and roll it has (its detector's floor
estimate refines those); one with no pose at all is named, since the walk cannot give
its height.
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

    sources = [bool(args.sim), args.detections is not None, args.live is not None]
    if sum(sources) != 1:
        return fail("walk: give one of --sim, --detections FILE or --live SECONDS")
    try:
        network = network_of(args)
        if args.sim:
            session, result, reference = _solve(network, args)
            tracks, believed = session.tracks, session.believed_poses
        else:
            tracks, believed, bases = _recorded(network, args)
            result = _solve_recorded(network, tracks, believed, args)
        if not result.accepted:
            print(f"openptrack calibrate: refinement refused: {result.note}", file=sys.stderr)
            return REFUSED
        entries = _entries(network, result, None if args.sim else bases)
        written = write(args, network, entries)
        if args.plot is not None:
            from openptrack_py.calibration.plots import plot_walk

            start = believed if args.refine else result.solved_poses
            plot_walk(args.plot, tracks, start, result)
    except (CalibrationError, ConfigError, ValueError) as exc:
        print(f"openptrack calibrate: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    if args.sim:
        rows = _rows(session, result, reference)
        columns = ["sensor", "error_cm", "error_deg", "clock_error_ms", "residual_cm"]
    else:
        rows, columns = _pose_rows(result), ["sensor", "x", "y", "yaw_deg", "clock_offset_ms"]
        columns.append("residual_cm")
    if result.spread:
        columns += ["spread_cm", "spread_deg", "spread_ms"]
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


def _recorded(network: Any, args: argparse.Namespace) -> tuple[tuple, dict, dict]:
    """Floor-frame tracks of a recorded or live walk, believed floor poses, 3-D bases.

    A sensor's base is the 3-D pose its detector believed (calibration entry, else the
    network's ``pose``): the walk replaces its ``x``, ``y`` and heading and keeps its
    height, tilt and roll (which the detector's own floor estimate refines).
    """
    from openptrack_py.calibration.files import believed_poses
    from openptrack_py.calibration.walk import Pose2D, tracks_from_batches
    from openptrack_py.geometry import pose_from_transform

    matrices = believed_poses(network)
    if args.detections is not None:
        from openptrack_py.eval.external import read_detections

        batches = [frame.batch for frame in read_detections(args.detections)]
    else:
        batches = _listen(network, args)
    listed = {s.id for s in network.sensors}
    strangers = sorted({b.sensor_id for b in batches} - listed)
    if strangers:
        raise ValueError(
            f"walk: detections of sensors the network does not list: {', '.join(strangers)}"
        )
    tracks = tracks_from_batches(batches, matrices)
    bases = {sid: pose_from_transform(m) for sid, m in matrices.items()}
    missing = [t.sensor_id for t in tracks if t.sensor_id not in bases]
    if missing:
        raise ValueError(
            f"walk: sensor {', '.join(missing)} has no pose in the network file: give at "
            "least its height and tilt (pose: {z: ..., pitch_deg: ...}); the walk finds "
            "its x, y and heading"
        )
    believed = {sid: Pose2D.from_pose(base) for sid, base in bases.items()}
    return tracks, believed, bases


def _solve_recorded(network: Any, tracks: tuple, believed: dict, args: argparse.Namespace) -> Any:
    from openptrack_py.calibration.walk import calibrate_walk, refine_walk

    if args.refine:
        poses = {t.sensor_id: believed[t.sensor_id] for t in tracks}
        return refine_walk(tracks, poses, frame="floor")
    # the world frame: where the network (or its calibration) places the first sensor
    reference = next(s.id for s in network.sensors if s.id in {t.sensor_id for t in tracks})
    return calibrate_walk(tracks, reference=reference, reference_pose=believed[reference])


def _listen(network: Any, args: argparse.Namespace) -> list:
    """Every detection batch the network publishes for ``--live`` seconds, with progress."""
    import time

    from openptrack_py.cli.common import ProgressLine
    from openptrack_py.messages.codec import decode_detection_batch
    from openptrack_py.runtime.args import bus_from_args
    from openptrack_py.transport.keys import SiteKeys

    batches: list = []
    seen: dict[str, int] = {s.id: 0 for s in network.sensors}
    malformed = 0

    def on_batch(sample: Any) -> None:
        nonlocal malformed
        try:
            batch = decode_detection_batch(sample.payload)
        except Exception:
            malformed += 1
            return
        batches.append(batch)
        seen[batch.sensor_id] = seen.get(batch.sensor_id, 0) + len(batch.detections)

    line = ProgressLine(every_s=0.0)
    with bus_from_args(network, args) as bus:
        bus.subscribe(SiteKeys(network.site).detections("*"), on_batch)
        start = time.monotonic()
        while (left := args.live - (time.monotonic() - start)) > 0:
            time.sleep(min(1.0, left))
            counts = " ".join(f"{sid}:{n}" for sid, n in sorted(seen.items()))
            line.show(f"walk: {max(left - 1.0, 0.0):.0f} s left | detections {counts}"[:200])
    line.done()
    if malformed:
        print(f"walk: {malformed} malformed batches dropped", file=sys.stderr)
    return list(batches)


def _pose_rows(result: Any) -> list[dict[str, Any]]:
    return [
        {
            "sensor": sid,
            "x": round(pose.x, 4),
            "y": round(pose.y, 4),
            "yaw_deg": round(pose.yaw_deg, 3),
            "clock_offset_ms": round(1000 * float(result.clock_offsets_s.get(sid, 0.0)), 1),
            "residual_cm": round(100 * float(result.residual_m.get(sid, math.nan)), 2),
            **_spread_row(result, sid),
        }
        for sid, pose in result.poses.items()
    ]


def _spread_row(result: Any, sid: str) -> dict[str, float]:
    """A sensor's spread between the walk's halves (empty where there is none)."""
    spread = result.spread.get(sid)
    if spread is None:
        return {}
    return {
        "spread_cm": round(100 * spread.position_m, 2),
        "spread_deg": round(spread.yaw_deg, 3),
        "spread_ms": round(1000 * spread.clock_s, 1),
    }


def _entries(network: Any, result: Any, bases: dict | None = None) -> dict:
    from openptrack_py.calibration.files import SensorCalibration
    from openptrack_py.geometry import world_from_optical

    entries = {}
    for sensor in network.sensors:
        base = sensor.pose if bases is None else bases.get(sensor.id)
        if sensor.id not in result.poses or base is None:
            continue
        pose = result.poses[sensor.id].to_pose(base)  # height, tilt, roll kept
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
                **_spread_row(result, sid),
            }
        )
    return rows
