"""``openptrack analyze``: trajectories, motion ranges, distances and places of a recording."""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from openptrack_py.cli.common import EXIT_CONFIG, ProgressLine, print_rows

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers


def add_parser(subparsers: Subparsers) -> None:
    """Register ``analyze``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
        "analyze",
        help="behaviour analytics of a recording (tables, CSV, an HTML report)",
        description="Read a recording's tracks (or its ground truth) in one streaming pass "
        "and report per person the time seen, trajectory length (momentum), motion areas "
        "(bounding rectangle, convex hull, the cells holding 90%% of their time) and speed; "
        "per pair the relative distance (mean, standard deviation, least); per zone and door "
        "of the network file the time spent and the crossings; and where people were. "
        "--html writes a report with plots that opens in any browser.",
    )
    p.add_argument("file", type=Path, help="the recording (.mcap or .jsonl)")
    p.add_argument("-c", "--config", help="network file whose zones and doors to use")
    p.add_argument("--truth", action="store_true", help="analyse the ground truth instead")
    p.add_argument("--rate", type=float, default=10.0, help="frames per second read (10)")
    p.add_argument("--html", type=Path, help="write the HTML report here")
    p.add_argument("--csv", type=Path, metavar="DIR", help="write every table as CSV here")
    p.add_argument(
        "--table", choices=("people", "pairs", "zones", "dwell", "doors"), default="people",
        help="the table printed (default people)",
    )  # fmt: skip
    p.add_argument("--format", choices=("table", "json", "markdown"), default="table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Analyse; print a table; status 2 for a missing file or a bad network file."""
    from openptrack_py.analytics import analyze, frames_from_recording
    from openptrack_py.analytics.report import write_report
    from openptrack_py.errors import ConfigError, WireFormatError

    if not args.file.is_file():
        print(f"openptrack analyze: no file {args.file}", file=sys.stderr)
        return EXIT_CONFIG
    zones, doors = (), ()
    try:
        if args.config:
            from openptrack_py.config import load_network
            from openptrack_py.runtime.args import resolve_config_path

            network = load_network(resolve_config_path(args.config))
            zones, doors = network.zones, network.doors
        if not args.rate > 0:
            raise ConfigError(f"--rate: must be > 0, got {args.rate}")
        progress = ProgressLine()
        first: list[float] = []

        def show(t: float) -> None:
            first.append(t) if not first else None
            progress.show(f"analyze {args.file.name}: {t - first[0]:8.1f} s of recording")

        source = "ground_truth" if args.truth else "tracks"
        recording, frames = frames_from_recording(
            args.file, source=source, rate_hz=args.rate, on_progress=show
        )
        analysis = analyze(frames, zones=zones, doors=doors)
        progress.done()
    except (ConfigError, WireFormatError) as exc:
        print(f"openptrack analyze: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    if recording.stopped:
        print(f"openptrack analyze: {recording.stopped}", file=sys.stderr)
    if not analysis.frames:
        print(f"openptrack analyze: {args.file} has no {source} messages", file=sys.stderr)
        return EXIT_CONFIG
    tables = analysis.tables()
    if args.csv is not None:
        _write_csv(tables, args.csv)
        print(f"wrote the tables to {args.csv}", file=sys.stderr)
    if args.html is not None:
        write_report(analysis, args.html, source=str(args.file))
        print(f"wrote {args.html}", file=sys.stderr)
    rows = tables[args.table]
    if args.format == "json":
        print(json.dumps(rows))
    elif rows:
        print_rows(rows, list(rows[0]), args.format)
    return 0


def _write_csv(tables: dict[str, list[dict[str, object]]], folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for name, rows in tables.items():
        with (folder / f"{name}.csv").open("w", newline="") as f:
            if rows:
                writer = csv.DictWriter(f, fieldnames=list(rows[0]))
                writer.writeheader()
                writer.writerows(rows)
