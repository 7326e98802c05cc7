"""``openptrack calibrate checkerboard --live | --recordings``: the procedure on real sensors.

The bodies of the live and recorded paths of
:func:`openptrack_py.cli.calibrate.run_checkerboard`. Live, each sensor's machine runs
``openptrack node board`` while someone moves the board through the room, holds it
still at each placement for a second or two and ends by laying it flat on the floor;
the nodes publish what they see of the board, and :func:`from_live` gathers it with the
progress in the terminal and on ``opt/<site>/board_progress`` (the web view draws it).
Recorded, each sensor's computer records the session while someone moves the board through the
room, holds it still at each placement for a second or two and ends by laying it flat on
the floor (``openptrack record-sensor SOURCE DIR/<sensor id>``); the recordings are
brought to one folder and read here in time order, all sensors at once, with the
progress shown as if live (who sees the board, views per pair, image coverage). Still
runs of the board become views (:mod:`~openptrack_py.calibration.capture`) and every
pose is solved jointly (:func:`~openptrack_py.calibration.extrinsics.calibrate_extrinsics`):
both paths feed one :class:`~openptrack_py.calibration.board_collector.BoardCollector`.
``--sim --record DIR`` writes a simulated session as such recordings.
"""

from __future__ import annotations

import argparse
import heapq
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from openptrack_py.errors import CalibrationError


def board_from_arg(text: str) -> Any:
    """The board of ``--board ROWSxCOLSxSQUARE`` (e.g. ``5x6x0.12``)."""
    from openptrack_py.calibration.checkerboard import Checkerboard

    return Checkerboard.parse(text)


def refine_options(args: argparse.Namespace) -> dict[str, Any]:
    """The solve's intrinsics options from ``--refine-intrinsics`` and ``--lens``."""
    from openptrack_py.calibration.evidence import REFINE_LEVEL

    return {
        "refine_intrinsics": getattr(args, "refine_intrinsics", False),
        "lens": getattr(args, "lens", "radial"),
        "refine_level": None if getattr(args, "always_refine", False) else REFINE_LEVEL,
    }


def record_sim(network: Any, args: argparse.Namespace) -> list[Path]:
    """Write the network's simulated session as one recording per sensor."""
    from openptrack_py.eval.board_stream import sim_board_session
    from openptrack_py.eval.checkerboard import record_board_session

    board = board_from_arg(args.board)
    sensors, room, session = sim_board_session(
        network, board, seed=args.seed, placements=args.placements
    )
    folders = record_board_session(sensors, room, session, args.record, seed=args.seed + 1)
    return list(folders.values())


def from_recordings(network: Any, args: argparse.Namespace, progress_view: Callable) -> Any:
    """Calibrate from ``DIR/<sensor id>`` recordings; the ``ExtrinsicCalibration``."""
    from openptrack_py.calibration.board_collector import BoardCollector
    from openptrack_py.calibration.capture import StillBoardViews
    from openptrack_py.detection.sources import open_source

    board = board_from_arg(args.board)
    folders = {s.id: args.recordings / s.id for s in network.sensors}
    missing = [f"{sid} ({path})" for sid, path in folders.items() if not path.is_dir()]
    if missing:
        raise CalibrationError(f"checkerboard: no recording for sensor {', '.join(missing)}")
    types = {s.id: s.type for s in network.sensors}
    progress = progress_view(_progress(network))
    collector = BoardCollector(folders, progress)
    views = {sid: StillBoardViews(sid, types[sid], board) for sid in folders}
    sources = {sid: open_source(str(path)) for sid, path in folders.items()}
    last = 0.0
    try:
        for stamp, sid, frame in _in_time_order(sources):
            collector.add(views[sid].report(frame))
            last = stamp
    finally:
        for source in sources.values():
            source.close()
    for still in views.values():
        collector.add(still.end_report(last))
    progress.done()  # end the progress line
    return solve(network, args, board, collector)


def from_live(network: Any, args: argparse.Namespace, progress_view: Callable) -> Any:
    """Calibrate from the sensors' board reports over Zenoh; the ``ExtrinsicCalibration``.

    Listens on ``opt/<site>/board/*`` for ``--live`` seconds, or until every sensor's
    board node said its source ran out, and republishes the progress on
    ``opt/<site>/board_progress`` for the web view.
    """
    import time

    import orjson

    from openptrack_py.calibration.board_collector import BoardCollector
    from openptrack_py.runtime.args import bus_from_args
    from openptrack_py.runtime.stop import stop_on_signals
    from openptrack_py.transport.keys import SiteKeys

    board = board_from_arg(args.board)  # a bad --board is refused before listening
    keys = SiteKeys(network.site)
    with bus_from_args(network, args) as bus:
        publisher = bus.publisher(keys.board_progress)

        def publish(snapshot: Any) -> None:
            publisher.put(orjson.dumps({**snapshot.to_dict(), "site": network.site}))

        shown = _Announced(progress_view(_progress(network)), publish)
        collector = BoardCollector([s.id for s in network.sensors], shown, board=board.spec)
        subscription = bus.subscribe(
            keys.board("*"), lambda s: collector.take(s.key, s.payload, time.monotonic())
        )
        start = time.monotonic()
        try:
            with stop_on_signals() as stop:  # Ctrl-C: the session is over, solve what came
                while time.monotonic() - start < args.live and not collector.finished:
                    if stop.wait(0.1):
                        print("\ncheckerboard: stopped listening (Ctrl-C)", file=sys.stderr)
                        break
        finally:
            subscription.close()
        final = shown.inner.snapshot()
        publish(final)
    shown.inner.done()
    dropped = {k: n for k, n in collector.counts.items() if k not in ("reports", "views") and n}
    if dropped:
        text = ", ".join(f"{n} {k}" for k, n in dropped.items())
        print(f"checkerboard: reports dropped: {text}", file=sys.stderr)
    if collector.other_board:
        theirs = ", ".join(
            f"{sid} {r}x{c}x{q:g}" for sid, (r, c, q) in sorted(collector.other_board.items())
        )
        raise CalibrationError(
            f"checkerboard: board nodes look for another board than --board {args.board} "
            f"({theirs}); give every node and this command the same --board"
        )
    silent = [s.id for s in network.sensors if s.id not in collector.reporting]
    if silent:
        raise CalibrationError(
            f"checkerboard: no report from {', '.join(silent)} in {args.live:g} s (is "
            "'openptrack node board' running on each sensor's machine, reaching this one?)"
        )
    return solve(network, args, board, collector)


class _Announced:
    """A progress display that also hands every snapshot to ``publish``."""

    def __init__(self, inner: Any, publish: Callable[[Any], None]) -> None:
        self.inner = inner
        self.publish = publish

    def observe(self, stamp: float, seeing: Any, views: Any) -> Any:
        snapshot = self.inner.observe(stamp, seeing, views)
        self.publish(snapshot)
        return snapshot


def _progress(network: Any) -> Any:
    from openptrack_py.calibration.progress import CalibrationProgress
    from openptrack_py.sensor_types import SENSOR_TYPES

    return CalibrationProgress(
        {s.id: (SENSOR_TYPES[s.type].width, SENSOR_TYPES[s.type].height) for s in network.sensors}
    )


def solve(network: Any, args: argparse.Namespace, board: Any, collector: Any) -> Any:
    """Every pose from a session's views of ``board`` (``--floor-board`` sets the world)."""
    from openptrack_py.calibration.extrinsics import calibrate_extrinsics
    from openptrack_py.calibration.files import believed_poses

    observations = collector.views
    intrinsics = collector.intrinsics
    unknown = [sid for sid, k in intrinsics.items() if k is None]
    if unknown:
        raise CalibrationError(
            f"checkerboard: no still view of the board from {', '.join(unknown)} (hold the "
            "board still for a second where each sensor sees it)"
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
        **refine_options(args),
    )


def _in_time_order(sources: dict[str, Any]) -> Iterator[tuple[float, str, Any]]:
    """Every sensor's frames merged by stamp."""

    def tagged(sid: str, source: Any) -> Iterator[tuple[float, str, Any]]:
        for frame in source.frames():
            yield frame.stamp, sid, frame

    streams = [tagged(sid, source) for sid, source in sources.items()]
    return heapq.merge(*streams, key=lambda item: (item[0], item[1]))


def rows(calibration: Any) -> tuple[list[dict[str, Any]], list[str]]:
    """Per sensor: views, reprojection RMS, the pose found (and refined intrinsics and lens)."""
    from openptrack_py.cli.common import pose_cells
    from openptrack_py.detection.lens import LENS_TERMS

    report = calibration.report
    out = []
    for sid, pose in calibration.poses().items():
        out.append(
            {
                "sensor": sid,
                "views": report.views[sid],
                "rms_px": round(report.rms_px[sid], 3),
                **pose_cells(pose),
            }
        )
        k = calibration.intrinsics.get(sid)
        if k is not None:
            pinhole = {"fx": k.fx, "fy": k.fy, "cx": k.cx, "cy": k.cy}
            out[-1].update((name, round(v, 2)) for name, v in pinhole.items())
            lens = zip(LENS_TERMS, k.distortion, strict=True)
            out[-1].update((name, round(float(c), 5)) for name, c in lens)
    columns = ["sensor", "views", "rms_px", "x", "y", "z", "yaw_deg", "pitch_deg", "roll_deg"]
    if calibration.intrinsics:
        solved = [k.distortion for k in calibration.intrinsics.values()]
        # --lens full, or a reported lens whose p1, p2, k3 were kept
        full = any(any(c != 0.0 for c in d[2:]) for d in solved)
        columns += ["fx", "fy", "cx", "cy", *LENS_TERMS[: 5 if full else 2]]
    return out, columns
