"""``openptrack eval``: score a tracker on simulated scenarios, or on files, and print it.

Named ``eval_tracker`` so it neither shadows the builtin ``eval`` nor is confused with
:mod:`openptrack_py.eval`, the scoring library it calls.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from openptrack_py.cli.common import EXIT_CONFIG, print_rows

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers

PROFILES = ("ideal", "realistic", "harsh")
"""The simulator's noise profiles (named here so that ``--help`` imports no simulator)."""

FILES_HELP = """\
bring your own data (instead of --scenario):
  openptrack eval --ground-truth GT --detections DETS [--tracks TRACKS ...]
runs the tracker on DETS and/or scores each TRACKS file (another tracker's output), one
row each. Formats by extension, .csv (header row first) or .jsonl (one JSON object per
line, same keys); time in seconds, any origin, one clock for all files:
  ground truth  time,id,x,y[,covered]      rows of one time = one frame; covered 0/1
                                           (default 1); empty id = a frame with nobody
  detections    time,sensor,x,y[,confidence,z,height,distance,arrival]
                rows of one (time, sensor) = one sensor frame; empty x,y = it saw
                nobody; defaults: confidence 1, height 1.7 m, z = height/2,
                distance 3 m, arrival = time + --latency
  tracks        time,id,x,y[,vx,vy]        rows of one time = one tracker output
A recording of `openptrack node record` (.jsonl) serves as any of the three. Rows in
time order (detections: in order of arrival).
"""


def add_parser(subparsers: Subparsers) -> None:
    """Register ``eval``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
        "eval",
        help="score a tracker on simulated scenarios (faster than real time) or on files",
        description="Run scenarios faster than real time through a tracker, or run it on "
        "detections from files, and print CLEAR MOT, identity and duplicate metrics.",
        epilog=FILES_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--scenario", action="append", help="scenario name, or 'all' (repeatable)")
    p.add_argument("--seed", type=int, action="append", help="seed (repeatable)")
    p.add_argument("--duration", type=float, help="simulated seconds (scenario default)")
    p.add_argument(
        "--profile",
        choices=PROFILES,
        help="simulator noise profile (default: realistic, where the simulator has profiles)",
    )
    p.add_argument(
        "--embeddings",
        action="store_true",
        help="sensors also send identity embeddings (a face recogniser's output, simulated)",
    )
    p.add_argument("--tracker", default=None, help="tracker to evaluate (ukf, or truth)")
    p.add_argument("--tracker-config", type=Path, help="YAML file of tracker parameters")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--max-distance", type=float, default=0.5, help="match distance, metres")
    p.add_argument(
        "--sensor-model",
        choices=("detections", "rgbd"),
        default="detections",
        help="rgbd: render images and run the real detector (slower)",
    )
    files = p.add_argument_group("files (see below)")
    files.add_argument("--ground-truth", type=Path, metavar="GT", help="ground-truth file")
    files.add_argument("--detections", type=Path, metavar="DETS", help="detections to track")
    files.add_argument(
        "--tracks",
        type=Path,
        action="append",
        metavar="TRACKS",
        help="a tracker's output to score (repeatable)",
    )
    files.add_argument(
        "--latency",
        type=float,
        default=0.0,
        help="seconds from capture to arrival of detections without an arrival column",
    )
    p.add_argument("--format", choices=("json", "table", "markdown"), default="table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Score the tracker on every scenario and seed asked for, or on files; one row per run."""
    from openptrack_py.eval.trackers import TRACKERS

    if args.tracker is not None and args.tracker not in TRACKERS:
        print(
            f"openptrack eval: unknown tracker {args.tracker!r} (allowed: {', '.join(TRACKERS)})",
            file=sys.stderr,
        )
        return EXIT_CONFIG
    if args.ground_truth is not None or args.detections is not None or args.tracks:
        return _run_files(args)
    return _run_scenarios(args)


def _run_scenarios(args: argparse.Namespace) -> int:
    from openptrack_py.eval.trackers import (
        DEFAULT_PROFILE,
        DEFAULT_TRACKER,
        run_eval,
        simulator_has_profiles,
    )
    from openptrack_py.sim.scenarios import SCENARIO_NAMES

    tracker = args.tracker or DEFAULT_TRACKER
    profile = args.profile
    if profile is None and simulator_has_profiles():
        profile = DEFAULT_PROFILE
    if args.embeddings:
        profile = f"{profile or DEFAULT_PROFILE}+embeddings"
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
                tracker=tracker,
                tracker_config=args.tracker_config,
                overrides=args.overrides,
                max_distance_m=args.max_distance,
                sensor_model=args.sensor_model,
                profile=profile,
            )
            head = {"tracker": tracker} | ({"profile": profile} if profile else {})
            rows.append(head | result.to_dict())
    columns = ["scenario", "seed", "mota", "motp", "idf1", "id_switches", "fp", "fn"]
    columns += ["duplicates", "returns", "returns_kept", "seen", "idf1_seen", "frames"]
    columns += ["realtime_factor"]
    print_rows(rows, columns, args.format)
    return 0


def _run_files(args: argparse.Namespace) -> int:
    from openptrack_py.eval.trackers import DEFAULT_TRACKER, run_file_eval

    refused = [
        flag
        for flag, given in (
            ("--scenario", args.scenario),
            ("--seed", args.seed),
            ("--duration", args.duration is not None),
            ("--profile", args.profile),
            ("--embeddings", args.embeddings),
            ("--sensor-model", args.sensor_model != "detections"),
        )
        if given
    ]
    problem = None
    if args.ground_truth is None:
        problem = "--detections and --tracks need --ground-truth"
    elif args.detections is None and not args.tracks:
        problem = "--ground-truth needs --detections or --tracks"
    elif refused:
        problem = f"{', '.join(refused)} apply to simulated scenarios, not to files"
    elif args.detections is None and (args.tracker or args.tracker_config or args.overrides):
        problem = "tracks files are scored as they are: tracker options need --detections"
    if problem:
        print(f"openptrack eval: {problem}", file=sys.stderr)
        return EXIT_CONFIG
    rows = []
    common = {"ground_truth": str(args.ground_truth)}
    if args.detections is not None:
        tracker = args.tracker or DEFAULT_TRACKER
        result = run_file_eval(
            args.ground_truth,
            detections=args.detections,
            tracker=tracker,
            tracker_config=args.tracker_config,
            overrides=args.overrides,
            latency_s=args.latency,
            max_distance_m=args.max_distance,
        )
        head = {"tracker": tracker, **common, "detections": str(args.detections)}
        rows.append(head | result.to_dict())
    for tracks in args.tracks or ():
        result = run_file_eval(args.ground_truth, tracks=tracks, max_distance_m=args.max_distance)
        head = {"tracker": tracks.name, **common, "tracks": str(tracks)}
        rows.append(head | result.to_dict())
    columns = ["tracker", "mota", "motp", "idf1", "id_switches", "fp", "fn", "duplicates"]
    columns += ["frames", "gt_objects"]
    print_rows(rows, columns, args.format)
    return 0
