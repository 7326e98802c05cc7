"""``openptrack calibrate``: place every sensor in one world frame, and check the result.

Subcommands:

``checkerboard NETWORK --live SECONDS | --recordings DIR | --sim``
    The checkerboard procedure (Munaro et al., OpenPTrack, §4): a board moved through
    the room and held still at each placement, corners found in each sensor's colour or
    infrared image, every pose solved jointly, the world frame from the board laid on
    the floor at the end. ``--live SECONDS`` gathers what each sensor's machine reports
    of the board (``openptrack node board``) over Zenoh, showing the progress in the
    terminal and the web view. ``--recordings DIR`` reads the session as each sensor
    recorded it (``openptrack record-sensor SOURCE DIR/<sensor id>`` on each sensor's
    computer) and prints per sensor its views, reprojection error and pose; ``--sim``
    plays it on the network's simulated sensors and prints the error against their
    true poses (``--sim --record DIR`` writes that session as recordings instead).
``walk NETWORK --sim | --detections FILE | --live SECONDS``
    Calibration with no checkerboard from one person walking (poses on the floor and
    clock offsets), or ``--refine`` the network's current calibration from a walk: a
    simulated walk, a recorded one, or the running network's detections.
``show FILE``
    Validate a calibration file and print its poses.

``--output FILE`` writes the result as a calibration file; ``--apply`` writes it into the
network's own calibration file (kept atomically: the running ``calibration`` node
publishes the change and every detector applies it). Exit status 2 for a refused input
(a board never seen, too few shared views, a walk that covers too little, an invalid
file), with one message naming what is wrong; nothing is written then.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from openptrack_py.cli.common import EXIT_CONFIG, ProgressLine, pose_cells, print_rows
from openptrack_py.runtime.args import add_zenoh_arguments

if TYPE_CHECKING:
    from openptrack_py.calibration.files import SensorCalibration
    from openptrack_py.cli.common import Subparsers
    from openptrack_py.config import NetworkConfig


def add_parser(subparsers: Subparsers) -> None:
    """Register ``calibrate``, its subcommands and their arguments."""
    p = subparsers.add_parser(
        "calibrate",
        help="calibrate the sensors (checkerboard, walking person) or check a calibration",
        description=__doc__.split("\n\n", 1)[1] if __doc__ else None,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = p.add_subparsers(dest="method", required=True)
    board = sub.add_parser("checkerboard", help="checkerboard calibration")
    _common(board)
    board.add_argument("--placements", type=int, default=30, help="board placements (sim)")
    _intrinsics_arguments(board)
    board.add_argument(
        "--recordings",
        type=Path,
        metavar="DIR",
        help="the session as recorded by each sensor: DIR/<sensor id> (openptrack record-sensor)",
    )
    board.add_argument(
        "--record",
        type=Path,
        metavar="DIR",
        help="with --sim: write the simulated session as those recordings, and stop",
    )
    board.add_argument(
        "--board",
        default="5x6x0.12",
        metavar="ROWSxCOLSxSQUARE",
        help="inner corners and square side in metres (default OpenPTrack's 5x6x0.12)",
    )
    board.add_argument(
        "--floor-board",
        choices=("last", "none"),
        default="last",
        help="the world frame: from the board laid on the floor at the end of the session "
        "(last), or from the first sensor's current pose (none)",
    )
    board.add_argument(
        "--live",
        type=float,
        metavar="SECONDS",
        help="listen to the sensors' board nodes (openptrack node board) this long, or "
        "until every one's source ends",
    )
    add_zenoh_arguments(board)
    board.set_defaults(func=run_checkerboard)
    walk = sub.add_parser("walk", help="calibration from one person walking")
    _common(walk)
    walk.add_argument("--seconds", type=float, default=60.0, help="length of the walk (sim)")
    walk.add_argument(
        "--detections", type=Path, help="recorded walk (recording, or eval's detections CSV)"
    )
    walk.add_argument(
        "--live", type=float, metavar="SECONDS", help="listen to the running network this long"
    )
    walk.add_argument("--refine", action="store_true", help="refine the network's current poses")
    walk.add_argument("--plot", type=Path, help="before/after top view (PNG)")
    add_zenoh_arguments(walk)
    walk.set_defaults(func=run_walk)
    show = sub.add_parser("show", help="validate a calibration file and print it")
    show.add_argument("file", type=Path)
    show.add_argument("-c", "--config", help="network file: also check the sensor ids")
    show.add_argument("--format", choices=("table", "json", "markdown"), default="table")
    show.set_defaults(func=run_show)


def _intrinsics_arguments(board: argparse.ArgumentParser) -> None:
    """The checkerboard's options on the sensors' own camera models."""
    own = board.add_mutually_exclusive_group()
    own.add_argument(
        "--intrinsics", action="store_true", help="estimate intrinsics first, per sensor (sim)"
    )
    own.add_argument(
        "--refine-intrinsics",
        action="store_true",
        help="solve every sensor's focal lengths, centre and lens distortion with the "
        "poses (for units whose intrinsics differ from their type's or from what they "
        "report; written to the file); a sensor keeps its given intrinsics where its "
        "views do not show them wrong",
    )
    board.add_argument(
        "--always-refine",
        action="store_true",
        help="with --refine-intrinsics: keep every sensor's refinement, even where its "
        "views do not show its given intrinsics wrong",
    )
    board.add_argument(
        "--lens",
        choices=("radial", "full"),
        default="radial",
        help="lens terms --refine-intrinsics solves: radial k1, k2 (default), or full: "
        "OpenCV's k1, k2, p1, p2, k3 (needs placements reaching the image's corners)",
    )


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("config", help="network file (or a preset name such as 'demo')")
    p.add_argument("--sim", action="store_true", help="run on the network's simulation")
    p.add_argument("--seed", type=int, default=0, help="simulation seed")
    p.add_argument("--output", type=Path, help="write the result as a calibration file")
    p.add_argument(
        "--apply", action="store_true", help="write it into the network's calibration file"
    )
    p.add_argument("--format", choices=("table", "json", "markdown"), default="table")


def _network(args: argparse.Namespace) -> NetworkConfig:
    from openptrack_py.config import load_network
    from openptrack_py.runtime.args import resolve_config_path

    return load_network(resolve_config_path(args.config))


def _fail(text: object) -> int:
    print(f"openptrack calibrate: {text}", file=sys.stderr)
    return EXIT_CONFIG


def _target(args: argparse.Namespace, network: NetworkConfig) -> Path | None:
    """Where ``--output``/``--apply`` ask to write (checked before any work is done)."""
    if not args.apply:
        return args.output
    if network.calibration is None:
        raise ValueError(
            "--apply: the network names no 'calibration' file (add one, or use --output)"
        )
    return Path(network.calibration)


def _write(args: argparse.Namespace, network: NetworkConfig, entries: dict) -> str | None:
    """Write ``entries`` where ``--output``/``--apply`` ask; the path written, if any."""
    from openptrack_py.calibration.files import CalibrationFile, load_calibration, save_calibration

    target = _target(args, network)
    if target is None:
        return None
    base = load_calibration(target) if target.exists() else CalibrationFile()
    save_calibration(target, base.replaced(entries))
    return str(target)


def _network_for_writing(args: argparse.Namespace) -> NetworkConfig:
    """The network, once ``--apply`` is known to have somewhere to write."""
    network = _network(args)
    _target(args, network)
    return network


def run_checkerboard(args: argparse.Namespace) -> int:
    """Calibrate by checkerboard; print per-sensor figures."""
    from openptrack_py.errors import CalibrationError, ConfigError

    if args.record is not None and not args.sim:
        return _fail("checkerboard: --record writes a simulated session: it needs --sim")
    if args.lens != "radial" and not args.refine_intrinsics:
        return _fail(f"checkerboard: --lens {args.lens} is solved by --refine-intrinsics: add it")
    if args.always_refine and not args.refine_intrinsics:
        return _fail("checkerboard: --always-refine keeps what --refine-intrinsics solves: add it")
    if sum([bool(args.sim), args.recordings is not None, args.live is not None]) != 1:
        return _fail("checkerboard: give one of --sim, --recordings DIR or --live SECONDS")
    try:
        network = _network_for_writing(args)
        if args.record is not None:
            from openptrack_py.cli.calibrate_board import record_sim

            for folder in record_sim(network, args):
                print(f"wrote {folder}", file=sys.stderr)
            return 0
        if args.recordings is not None:
            from openptrack_py.cli.calibrate_board import from_recordings

            calibration = from_recordings(network, args, _TerminalProgress)
        elif args.live is not None:
            from openptrack_py.cli.calibrate_board import from_live

            calibration = from_live(network, args, _TerminalProgress)
        else:
            result = _checkerboard_sim(network, args)
            calibration = result.calibration
        written = _write(args, network, calibration.entries())
    except (CalibrationError, ConfigError, ValueError) as exc:
        return _fail(exc)
    for line in calibration.intrinsics_warnings():
        print(f"openptrack calibrate: {line}", file=sys.stderr)
    if args.recordings is not None or args.live is not None:
        from openptrack_py.cli.calibrate_board import rows

        print_rows(*rows(calibration), args.format)
        if written:
            print(f"wrote {written}", file=sys.stderr)
        return 0
    summary = result.to_dict()
    report = summary["report"]
    rows = [
        {
            "sensor": sid,
            "views": s["views"],
            "rms_px": round(report["rms_px"].get(sid, float("nan")), 3),
            "error_cm": round(s["translation_error_cm"], 2),
            "error_deg": round(s["rotation_error_deg"], 3),
        }
        for sid, s in summary["sensors"].items()
    ]
    print_rows(rows, ["sensor", "views", "rms_px", "error_cm", "error_deg"], args.format)
    if written:
        print(f"wrote {written}", file=sys.stderr)
    return 0


def _checkerboard_sim(network: NetworkConfig, args: argparse.Namespace) -> Any:
    from openptrack_py.calibration.progress import CalibrationProgress
    from openptrack_py.eval.board_stream import sim_sensors
    from openptrack_py.eval.checkerboard import simulate_checkerboard_calibration
    from openptrack_py.sensor_types import SENSOR_TYPES
    from openptrack_py.sim.live import scenario_from_network

    sensors = sim_sensors(network)
    room = scenario_from_network(network, calibrated=False).room
    sizes = {s.id: (SENSOR_TYPES[s.type].width, SENSOR_TYPES[s.type].height) for s in sensors}
    progress = _TerminalProgress(CalibrationProgress(sizes))
    from openptrack_py.cli.calibrate_board import board_from_arg, refine_options

    return simulate_checkerboard_calibration(
        sensors,
        room,
        board=board_from_arg(args.board),
        placements=args.placements,
        seed=args.seed,
        estimate_intrinsics=args.intrinsics,
        **refine_options(args),
        progress=progress,
    )


class _TerminalProgress:
    """Shows which sensors see the board, views per pair and coverage on one stderr line."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.line = ProgressLine(every_s=0.0)

    def update(self, stamp: float, found: dict) -> Any:
        return self._show(self.inner.update(stamp, found))

    def observe(self, stamp: float, seeing: Any, views: Any) -> Any:
        return self._show(self.inner.observe(stamp, seeing, views))

    def done(self) -> None:
        self.line.done()

    def _show(self, snap: Any) -> Any:
        seeing = ",".join(sorted(snap.seeing)) or "-"
        pairs = " ".join(f"{a}+{b}:{n}" for (a, b), n in sorted(snap.pair_views.items()))
        cover = " ".join(f"{s}:{c:.0%}" for s, c in sorted(snap.coverage.items()))
        self.line.show(f"board seen by {seeing} | pairs {pairs} | coverage {cover}"[:200])
        return snap

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


def run_walk(args: argparse.Namespace) -> int:
    """Calibrate (or refine) from one person walking; print per-sensor figures."""
    from openptrack_py.cli.calibrate_walk import walk

    return walk(args, _network_for_writing, _write, _fail)


def _entry_row(sensor_id: str, entry: SensorCalibration) -> dict[str, Any]:
    pose = entry.as_pose()
    return {
        "sensor": sensor_id,
        **pose_cells(pose),
        "clock_offset_s": entry.clock_offset_s,
        "method": entry.method,
        "date": entry.date.isoformat() if entry.date else "",
    }


def run_show(args: argparse.Namespace) -> int:
    """Validate a calibration file (and its sensor ids) and print it."""
    from openptrack_py.calibration.files import load_calibration, network_calibration
    from openptrack_py.errors import CalibrationError, ConfigError

    try:
        calibration = load_calibration(args.file)
        if args.config:
            from openptrack_py.config import load_network
            from openptrack_py.runtime.args import resolve_config_path

            network = load_network(resolve_config_path(args.config))
            network_calibration(network.model_copy(update={"calibration": args.file}))
    except (CalibrationError, ConfigError) as exc:
        return _fail(exc)
    rows = [_entry_row(sid, e) for sid, e in calibration.sensors.items()]
    columns = ["sensor", "x", "y", "z", "yaw_deg", "pitch_deg", "roll_deg"]
    print_rows(rows, [*columns, "clock_offset_s", "method"], args.format)
    return 0
