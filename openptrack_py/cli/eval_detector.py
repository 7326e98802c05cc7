"""``openptrack eval-detector``: score the people detector on rendered simulated scenes."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from openptrack_py.cli.common import (
    EXIT_CONFIG,
    add_detector_options,
    detector_config,
    print_rows,
)
from openptrack_py.errors import ConfigError

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers


def add_parser(subparsers: Subparsers) -> None:
    """Register ``eval-detector``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
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
    add_detector_options(p)
    p.add_argument("--format", choices=("json", "table"), default="table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Score the detector for every sensor type and scenario asked for; one row each."""
    from openptrack_py.eval.detector import evaluate_detector

    try:
        needed = args.preset or args.overrides or args.detector_config
        config = detector_config(args) if needed else None
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
    print_rows(rows, columns, args.format)
    return 0
