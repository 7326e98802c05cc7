"""The ``openptrack`` command.

Subcommands::

    openptrack launch NETWORK [--host NAME] [--duration S]   run this host's nodes
    openptrack node NAME [...]                               run one node in the foreground
    openptrack status [-c NETWORK]                           live nodes and their rates
    openptrack echo KEYEXPR [-c NETWORK]                     print messages as JSON lines
    openptrack config NODE [KEY=VALUE ...]                   change a running node's parameters
    openptrack eval --scenario NAME --seed N                 score a tracker on a scenario
    openptrack scenarios                                     list the simulated scenarios
    openptrack show-config NETWORK                           the validated network file
    openptrack record-sensor SOURCE OUTDIR                   record a depth source to a folder
    openptrack detect INPUT                                  detect people in depth frames
    openptrack eval-detector --scenario NAME                 score the detector on renderings

``openptrack <subcommand> --help`` explains each.
"""

from __future__ import annotations

import argparse
import json
import os
import pkgutil
import signal
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

import orjson

from openptrack_py import __version__
from openptrack_py.config import load_network, to_yaml
from openptrack_py.errors import ConfigError, WireFormatError
from openptrack_py.runtime.args import (
    add_common_arguments,
    bus_from_args,
    network_from_args,
    resolve_config_path,
)
from openptrack_py.runtime.logs import configure_logging

if TYPE_CHECKING:
    from openptrack_py.config import DetectorConfig
    from openptrack_py.sim.depth_source import SimDepthSource

EXIT_CONFIG = 2
RGBD_START_DELAY_S = 3.0
"""With ``sim.sensor_model: rgbd``, the shared scenario start this far after launch."""


# ------------------------------------------------------------------------ launch


def _cmd_launch(args: argparse.Namespace) -> int:
    from openptrack_py.launch import Supervisor, host_matches, plan_nodes, this_host
    from openptrack_py.runtime.status import StatusBoard
    from openptrack_py.transport.zenoh_bus import ZenohBus

    path = resolve_config_path(args.network)
    assert path is not None
    cfg = load_network(path, args.overrides)
    host = args.host or this_host()
    passthrough = [a for o in args.overrides for a in ("--set", o)]
    # With the live table, node logs would scroll it away: only warnings get through.
    level = "warning" if args.table and args.log_level == "info" else args.log_level
    passthrough += ["--log-level", level, "--log-format", args.log_format]
    if cfg.sim is not None and cfg.sim.sensor_model == "rgbd" and cfg.sim.start_time is None:
        # Rendering detectors and the simulator must play the same world at the same time.
        passthrough += ["--set", f"sim.start_time={time.time() + RGBD_START_DELAY_S:.3f}"]
    specs = plan_nodes(cfg, host, path.resolve(), passthrough)
    if not specs:
        print(f"openptrack launch: no node of {path} runs on host {host!r}", file=sys.stderr)
        return EXIT_CONFIG
    hub = None
    if cfg.zenoh.hub is not None and host_matches(cfg.zenoh.hub_host, host):
        try:
            hub = ZenohBus(cfg.zenoh, as_hub=True)
        except ConfigError as exc:
            print(
                f"openptrack launch: cannot open the hub {cfg.zenoh.hub}: {exc}", file=sys.stderr
            )
            return EXIT_CONFIG
    supervisor = Supervisor(specs)
    names = ", ".join(s.name for s in specs)
    supervisor.say("launch", f"site {cfg.site!r} on host {host!r}: starting {names}")
    if hub is not None:
        supervisor.say("launch", f"hub listening on {cfg.zenoh.hub}")

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        supervisor.say("launch", f"{signal.Signals(signum).name}: stopping all nodes")
        supervisor.request_stop()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    board = StatusBoard(hub, cfg.site) if hub is not None else None
    reporter = None
    if board is not None and (args.status_interval > 0 or args.table):
        import threading

        from openptrack_py.runtime.table import TrackView, render

        stop = threading.Event()
        view = TrackView(hub, cfg.site) if args.table else None
        redraw = sys.stdout.isatty()
        interval = 1.0 if args.table else args.status_interval

        def report() -> None:
            while not stop.wait(interval):
                if view is None:
                    supervisor.say("status", board.summary_line())
                elif redraw:  # a terminal: repaint in place, like top
                    supervisor.say_raw("\x1b[H\x1b[J" + render(view, board) + "\n")
                else:
                    for line in render(view, board).splitlines():
                        supervisor.say("table", line)

        reporter = threading.Thread(target=report, daemon=True)
        reporter.start()
    try:
        return supervisor.run(args.duration)
    finally:
        if reporter is not None:
            stop.set()
        if board is not None:
            board.close()
        if hub is not None:
            hub.close()


# -------------------------------------------------------------------------- node


def available_nodes() -> list[str]:
    """Names of the node modules shipped in ``openptrack_py.nodes``."""
    import openptrack_py.nodes as package

    return sorted(m.name for m in pkgutil.iter_modules(package.__path__) if not m.ispkg)


def _cmd_node(args: argparse.Namespace) -> int:
    nodes = available_nodes()
    if args.name not in nodes:
        print(
            f"openptrack node: unknown node {args.name!r} (available: {', '.join(nodes)})",
            file=sys.stderr,
        )
        return EXIT_CONFIG
    module = f"openptrack_py.nodes.{args.name}"
    os.execv(sys.executable, [sys.executable, "-m", module, *args.node_args])
    return 0  # pragma: no cover - execv does not return


# ------------------------------------------------------------------------ status


def _cmd_status(args: argparse.Namespace) -> int:
    from openptrack_py.eval.runner import format_table
    from openptrack_py.runtime.status import StatusBoard

    cfg = network_from_args(args)
    with bus_from_args(cfg, args) as bus:
        board = StatusBoard(bus, cfg.site)
        try:
            while True:
                time.sleep(args.wait)
                rows = board.rows()
                if args.format == "json":
                    print(orjson.dumps(rows).decode(), flush=True)
                else:
                    columns = ["node", "alive", "host", "pid", "uptime_s", "in_hz", "out_hz"]
                    columns += ["dropped", "malformed", "stats_age_s"]
                    text = format_table(rows, columns) if rows else "no live nodes"
                    print(f"site {cfg.site!r}:\n{text}", flush=True)
                if not args.watch:
                    return 0 if rows else 1
        except KeyboardInterrupt:
            return 0
        finally:
            board.close()


# -------------------------------------------------------------------------- echo


def _cmd_echo(args: argparse.Namespace) -> int:
    from openptrack_py.messages.by_key import decoder_for_key
    from openptrack_py.runtime.node import Inbox

    cfg = network_from_args(args)
    inbox: Inbox[tuple[float, str, bytes]] = Inbox(100_000)
    with bus_from_args(cfg, args) as bus:
        sub = bus.subscribe(args.keyexpr, lambda s: inbox.push((time.time(), s.key, s.payload)))
        deadline = None if args.duration is None else time.monotonic() + args.duration
        printed = malformed = 0
        try:
            while args.count is None or printed < args.count:
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    break
                item = inbox.get(timeout=0.2 if left is None else min(0.2, left))
                if item is None:
                    continue
                received, key, payload = item
                decode = None if args.raw else decoder_for_key(key)
                if decode is not None:
                    try:
                        decode(payload)
                    except WireFormatError as exc:
                        malformed += 1
                        print(f"malformed message on {key}: {exc}", file=sys.stderr)
                        continue
                try:
                    body = orjson.loads(payload)
                except orjson.JSONDecodeError:
                    body = {
                        "bytes": len(payload),
                        "text": payload[:200].decode("utf-8", "replace"),
                    }
                line = {"t": round(received, 6), "key": key, "msg": body}
                sys.stdout.write(orjson.dumps(line).decode() + "\n")
                sys.stdout.flush()
                printed += 1
        except (KeyboardInterrupt, BrokenPipeError):
            pass
        finally:
            sub.close()
    return 0


# ------------------------------------------------------------------------ config


def _cmd_config(args: argparse.Namespace) -> int:
    import uuid

    import yaml

    from openptrack_py.config import parse_override_value
    from openptrack_py.messages.codec import decode_config_ack, encode_config_update
    from openptrack_py.messages.config_update import ConfigUpdate
    from openptrack_py.runtime.node import Inbox
    from openptrack_py.transport import SiteKeys, wait_for_subscribers

    changes = {}
    for item in args.assignments:
        key, sep, text = item.partition("=")
        if not sep or not key:
            print(f"openptrack config: {item!r}: expected key=value", file=sys.stderr)
            return EXIT_CONFIG
        changes[key.removeprefix(f"{args.node}.")] = parse_override_value(text)
    cfg = network_from_args(args)
    keys = SiteKeys(cfg.site)
    request = ConfigUpdate(id=uuid.uuid4().hex[:16], set=changes)
    acks: Inbox[bytes] = Inbox(100)
    with bus_from_args(cfg, args) as bus:
        sub = bus.subscribe(keys.config_ack(args.node), lambda s: acks.push(s.payload))
        pub = bus.publisher(keys.config(args.node))
        if not wait_for_subscribers(pub, args.timeout):
            print(
                f"openptrack config: no node {args.node!r} listens on {keys.config(args.node)}",
                file=sys.stderr,
            )
            return 1
        pub.put(encode_config_update(request))
        deadline = time.monotonic() + args.timeout
        ack = None
        while ack is None and time.monotonic() < deadline:
            payload = acks.get(timeout=0.1)
            if payload is None:
                continue
            try:
                candidate = decode_config_ack(payload)
            except WireFormatError:
                continue
            if candidate.id == request.id:
                ack = candidate
        sub.close()
        pub.close()
    if ack is None:
        print(
            f"openptrack config: {args.node!r} did not answer in {args.timeout:g} s",
            file=sys.stderr,
        )
        return 1
    if args.format == "json":
        print(
            orjson.dumps(
                {"accepted": ack.accepted, "error": ack.error, "config": ack.config}
            ).decode()
        )
    elif not ack.accepted:
        pass
    elif changes:
        applied = " ".join(f"{k}={v}" for k, v in changes.items())
        print(f"{args.node}: applied {applied}")
    else:
        sys.stdout.write(yaml.safe_dump(ack.config, sort_keys=False))
    if not ack.accepted:
        print(f"openptrack config: {args.node} refused the update: {ack.error}", file=sys.stderr)
        return EXIT_CONFIG
    return 0


# -------------------------------------------------------------------------- eval


def _cmd_eval(args: argparse.Namespace) -> int:
    from openptrack_py.eval.trackers import DEFAULT_TRACKER, TRACKERS, run_eval

    args.tracker = args.tracker or DEFAULT_TRACKER
    if args.tracker not in TRACKERS:
        print(
            f"openptrack eval: unknown tracker {args.tracker!r} (allowed: {', '.join(TRACKERS)})",
            file=sys.stderr,
        )
        return EXIT_CONFIG
    from openptrack_py.sim.scenarios import SCENARIO_NAMES

    scenarios = args.scenario or ["crowd"]
    if "all" in scenarios:
        scenarios = list(SCENARIO_NAMES)
    seeds = args.seed or [0]
    rows = []
    for name in scenarios:
        for seed in seeds:
            result = run_eval(
                name,
                seed,
                duration_s=args.duration,
                tracker=args.tracker,
                tracker_config=args.tracker_config,
                overrides=args.overrides,
                max_distance_m=args.max_distance,
                sensor_model=args.sensor_model,
            )
            rows.append({"tracker": args.tracker, **result.to_dict()})
    columns = ["scenario", "seed", "mota", "motp", "idf1", "id_switches", "fp", "fn"]
    columns += ["frames", "gt_objects", "realtime_factor"]
    _print_rows(rows, columns, args.format)
    return 0


def _print_rows(rows: list[dict], columns: list[str], fmt: str) -> None:
    """Result rows as JSON (one object for one row), a Markdown table or a text table."""
    from openptrack_py.eval.runner import format_markdown, format_table

    if fmt == "json":
        one = len(rows) == 1
        print(json.dumps(rows[0] if one else rows, indent=None if one else 1))
    elif fmt == "markdown":
        print(format_markdown(rows, columns))
    else:
        print(format_table(rows, columns))


# --------------------------------------------------------------------- scenarios


def _cmd_scenarios(args: argparse.Namespace) -> int:
    from openptrack_py.sim.scenarios import describe_scenarios

    for name, text in describe_scenarios().items():
        print(f"{name:13s} {text}")
    return 0


def _cmd_show_config(args: argparse.Namespace) -> int:
    path = resolve_config_path(args.network)
    cfg = load_network(path, args.overrides)
    sys.stdout.write(to_yaml(cfg))
    return 0


# ----------------------------------------------------------------- record-sensor


def _cmd_record_sensor(args: argparse.Namespace) -> int:
    from collections.abc import Iterator

    from openptrack_py.detection.frame import Frame
    from openptrack_py.detection.sources import open_source, record_folder
    from openptrack_py.errors import SourceError

    def limited(frames: Iterator[Frame]) -> Iterator[Frame]:
        first = None
        try:
            for frame in frames:
                first = frame.stamp if first is None else first
                if args.seconds is not None and frame.stamp - first >= args.seconds:
                    return
                yield frame
        except KeyboardInterrupt:  # Ctrl-C ends a live recording; what was written stays
            return

    try:
        source = open_source(args.source)
        try:
            count = record_folder(limited(source.frames()), args.outdir, max_frames=args.frames)
        finally:
            source.close()
    except SourceError as exc:
        print(f"openptrack record-sensor: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    print(f"recorded {count} frames to {args.outdir}")
    return 0


# ------------------------------------------------------------------------ detect


def _detector_config(args: argparse.Namespace) -> DetectorConfig:
    from openptrack_py.config import DetectorConfig, load_config

    overrides = list(args.overrides)
    if args.preset:
        overrides.append(f"preset={args.preset}")
    if getattr(args, "ground", None):
        if args.ground == "auto":
            overrides.append("ground.mode=auto")
        else:
            try:
                plane = [float(v) for v in args.ground.split(",")]
            except ValueError:
                plane = []
            if len(plane) != 4:
                raise ConfigError(
                    f"--ground: expected 'auto' or four numbers a,b,c,d (received {args.ground!r})"
                )
            overrides += ["ground.mode=calibration", f"ground.plane=[{','.join(map(str, plane))}]"]
    return load_config(DetectorConfig, args.detector_config, overrides)


def _sim_source_factory(spec: str) -> SimDepthSource:
    """``sim:SCENARIO[:SENSOR]``: a scenario's sensor rendered faster than real time."""
    from openptrack_py.sim.depth_source import SimDepthSource
    from openptrack_py.sim.scenarios import build_scenario
    from openptrack_py.sim.simulator import DEFAULT_START_TIME

    _, _, rest = spec.partition(":")
    name, _, sensor = rest.partition(":")
    scenario = build_scenario(name or "crowd")
    sensor = sensor or scenario.sensors[0].id
    return SimDepthSource(scenario, sensor, start_time=DEFAULT_START_TIME, realtime=False)


def _add_detector_options(p: argparse.ArgumentParser) -> None:
    """The detector settings ``detect`` and ``eval-detector`` share (see _detector_config)."""
    from openptrack_py.config import HEIGHT_PRESETS

    p.add_argument("--preset", choices=tuple(HEIGHT_PRESETS), help="height band preset")
    p.add_argument("--detector-config", type=Path, help="YAML file of detector settings")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")


def _cmd_detect(args: argparse.Namespace) -> int:
    from openptrack_py.detection.pipeline import PeopleDetector
    from openptrack_py.detection.sources import open_source
    from openptrack_py.errors import SourceError
    from openptrack_py.eval.runner import format_table

    try:
        config = _detector_config(args)
        source = open_source(args.input, extra={"sim": _sim_source_factory})
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
            ground = [round(v, 5) for v in result.ground.coefficients] if result.ground else None
            record = {
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
            if args.format == "json":
                print(json.dumps(record), flush=True)
            else:
                for i, d in enumerate(record["detections"]):
                    x, y, z = d["position"]
                    sx, sy, sz = d["sensor_position"]
                    rows.append(
                        {
                            "frame": frame.seq, "n": i, "x": x, "y": y, "z": z,
                            "sensor_x": sx, "sensor_y": sy, "sensor_z": sz,
                            "height": d["height"], "conf": d["confidence"],
                            "frame_id": result.frame_id, "ground": ground,
                        }
                    )  # fmt: skip
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


def _cmd_eval_detector(args: argparse.Namespace) -> int:
    from openptrack_py.eval.detector import evaluate_detector

    try:
        needed = args.preset or args.overrides or args.detector_config
        config = _detector_config(args) if needed else None
    except ConfigError as exc:
        print(f"openptrack eval-detector: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    rows = []
    for sensor_type in args.sensor_type or ["kinect2"]:
        for name in args.scenario or ["crowd"]:
            rows.append(
                evaluate_detector(
                    name,
                    seed=args.seed,
                    sensor_type=sensor_type,
                    duration_s=args.duration,
                    sample_hz=args.sample_rate,
                    config=config,
                    match_radius_m=args.match_radius,
                )
            )
    columns = ["scenario", "sensor_type", "preset", "recall", "precision", "mean_error_m"]
    columns += ["p95_error_m", "frames", "expected", "fp", "fn", "detector_ms_p50"]
    _print_rows(rows, columns, args.format)
    return 0


# ------------------------------------------------------------------------ parser


def build_parser() -> argparse.ArgumentParser:
    """The ``openptrack`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="openptrack",
        description="Multi-sensor people tracking for creative apps.",
    )
    parser.add_argument("--version", action="version", version=f"openptrack {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser(
        "launch",
        help="start this host's nodes of a network file and supervise them",
        description="Start the nodes a network file assigns to this host, prefix their logs, "
        "restart crashed ones, stop all on Ctrl-C.",
    )
    p.add_argument("network", help="network file or preset name (e.g. demo)")
    p.add_argument("--host", help="host name to launch for (default: this machine)")
    p.add_argument("--duration", type=float, help="stop everything after S seconds")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument(
        "--status-interval", type=float, default=5.0, help="seconds between status lines (0: off)"
    )
    p.add_argument(
        "--table",
        action="store_true",
        help="show a live table of the tracks and node rates (node logs: warnings only)",
    )
    p.add_argument("--log-level", default="info", choices=("debug", "info", "warning", "error"))
    p.add_argument("--log-format", default="text", choices=("text", "json"))
    p.set_defaults(func=_cmd_launch)

    p = sub.add_parser(
        "node",
        help="run one node in the foreground",
        description="Run one node. Available nodes: "
        + ", ".join(available_nodes())
        + ". Arguments after the name go to the node (see 'openptrack node NAME --help').",
    )
    p.add_argument("name", help="node name")
    p.add_argument("node_args", nargs=argparse.REMAINDER, help="arguments for the node")
    p.set_defaults(func=_cmd_node)

    p = sub.add_parser(
        "status",
        help="list live nodes and their message rates",
        description="List the nodes of a site that are alive (Zenoh liveliness) with the "
        "rates from their latest stats.",
    )
    add_common_arguments(p)
    p.add_argument("--wait", type=float, default=2.5, help="seconds to listen before printing")
    p.add_argument("--watch", action="store_true", help="keep printing until Ctrl-C")
    p.add_argument("--format", choices=("table", "json"), default="table")
    p.set_defaults(func=_cmd_status)

    p = sub.add_parser(
        "echo",
        help="print the messages on a key expression as JSON lines",
        description="Print every message on KEYEXPR as a JSON line "
        '{"t": receive time, "key": ..., "msg": ...}. Invalid messages go to stderr.',
    )
    p.add_argument("keyexpr", help="key expression, e.g. 'opt/default/detections/**'")
    add_common_arguments(p)
    p.add_argument("-n", "--count", type=int, help="stop after N messages")
    p.add_argument("--duration", type=float, help="stop after S seconds")
    p.add_argument("--raw", action="store_true", help="do not validate messages")
    p.set_defaults(func=_cmd_echo)

    p = sub.add_parser(
        "config",
        help="change a running node's parameters (or show them)",
        description="Send a live parameter update to a running node, e.g. "
        "'openptrack config tracker gate_probability=0.99'. The node validates it, applies "
        "it between two steps and answers; without assignments the current parameters "
        "are printed. Exit status: 0 applied, 2 refused, 1 no answer.",
    )
    p.add_argument("node", help="node name, e.g. tracker")
    p.add_argument("assignments", nargs="*", metavar="KEY=VALUE", help="parameters to change")
    add_common_arguments(p)
    p.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for the node")
    p.add_argument("--format", choices=("text", "json"), default="text")
    p.set_defaults(func=_cmd_config)

    p = sub.add_parser(
        "eval",
        help="run a simulated scenario faster than real time through a tracker and score it",
        description="Run scenarios faster than real time through a tracker and print CLEAR "
        "MOT and identity metrics.",
    )
    p.add_argument("--scenario", action="append", help="scenario name, or 'all' (repeatable)")
    p.add_argument("--seed", type=int, action="append", help="seed (repeatable)")
    p.add_argument("--duration", type=float, help="simulated seconds (scenario default)")
    p.add_argument("--tracker", default=None, help="tracker to evaluate")
    p.add_argument("--tracker-config", type=Path, help="YAML file of tracker parameters")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--max-distance", type=float, default=0.5, help="match distance, metres")
    p.add_argument(
        "--sensor-model",
        choices=("detections", "rgbd"),
        default="detections",
        help="rgbd: render images and run the real detector (slower)",
    )
    p.add_argument("--format", choices=("json", "table", "markdown"), default="table")
    p.set_defaults(func=_cmd_eval)

    p = sub.add_parser("scenarios", help="list the simulated scenarios")
    p.set_defaults(func=_cmd_scenarios)

    p = sub.add_parser(
        "show-config",
        help="validate a network file and print it with every default filled in",
    )
    p.add_argument("network", help="network file or preset name")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.set_defaults(func=_cmd_show_config)

    p = sub.add_parser(
        "record-sensor",
        help="record a depth source (device, .bag, cloud, folder) to a folder of PNGs",
        description="Record the frames of a depth source to OUTDIR as uint16 millimetre "
        "depth PNGs (plus colour and intensity when present), frames.csv and "
        "intrinsics.json, a folder that can be replayed as a source. SOURCE is a folder "
        "(our recordings, TUM RGB-D, or depth PNGs with intrinsics.json), a .pcd/.ply "
        "cloud, a RealSense .bag, realsense[:SERIAL] or azure-kinect[:N]. A live device "
        "records until --frames, --seconds or Ctrl-C. Exit status 2 when the source "
        "cannot be opened or recorded.",
    )
    p.add_argument("source", help="source spec, e.g. realsense, capture.bag, ./tum_sequence")
    p.add_argument("outdir", type=Path, help="output folder (created; must be empty if it exists)")
    p.add_argument("--frames", type=int, metavar="N", help="stop after N frames")
    p.add_argument(
        "--seconds",
        type=float,
        metavar="S",
        help="stop after S seconds of recording (by the frames' timestamps)",
    )
    p.set_defaults(func=_cmd_record_sensor)
    p = sub.add_parser(
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
    _add_detector_options(p)
    p.add_argument("--ground", help="'auto' (estimate the floor) or a plane a,b,c,d")
    p.add_argument("--sensor-type", default=None, help="kinect1|kinect2|realsense|sr4500")
    p.add_argument("--frames", type=int, metavar="N", help="stop after N frames")
    p.add_argument(
        "--pose-from-sim", action="store_true", help="sim inputs: report in the world frame"
    )
    p.add_argument("--format", choices=("json", "table"), default="table")
    p.set_defaults(func=_cmd_detect)

    p = sub.add_parser(
        "eval-detector",
        help="score the people detector on rendered simulated scenes",
        description="Render a scenario from each of its sensors, run the detector and print "
        "recall, precision and mean / p95 floor position error against ground truth.",
    )
    p.add_argument("--scenario", action="append", help="scenario name (repeatable)")
    p.add_argument("--sensor-type", action="append", help="sensor type (repeatable)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--duration", type=float, default=30.0, help="simulated seconds")
    p.add_argument("--sample-rate", type=float, default=2.0, help="instants scored per second")
    p.add_argument("--match-radius", type=float, default=0.3, help="match distance, metres")
    _add_detector_options(p)
    p.add_argument("--format", choices=("json", "table"), default="table")
    p.set_defaults(func=_cmd_eval_detector)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``openptrack`` command."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command in ("status", "echo", "config"):
        configure_logging("openptrack", args.log_level, args.log_format)
    try:
        return int(args.func(args))
    except ConfigError as exc:
        print(f"openptrack {args.command}: {exc}", file=sys.stderr)
        return EXIT_CONFIG


if __name__ == "__main__":
    sys.exit(main())
