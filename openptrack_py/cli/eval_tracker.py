"""``openptrack eval``: run simulated scenarios through a tracker and print its scores.

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


def add_parser(subparsers: Subparsers) -> None:
    """Register ``eval``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
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
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Score the tracker on every scenario and seed asked for; print one row per run."""
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
    print_rows(rows, columns, args.format)
    return 0
