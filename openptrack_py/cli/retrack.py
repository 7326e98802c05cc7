"""``openptrack retrack``: re-run the tracker offline on a recording, with other settings."""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from openptrack_py.cli.common import EXIT_CONFIG, ProgressLine, print_rows

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers


def add_parser(subparsers: Subparsers) -> None:
    """Register ``retrack``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
        "retrack",
        help="re-run the tracker offline on a recording",
        description="Run the tracker on a recording's detections, faster than real time, "
        "with the settings the site ran (kept in the recording) changed by --set, and "
        "write the new tracks (and the ground truth) to --output. Steps are taken as the "
        "live tracker took them when the recording says (so the same settings give the "
        "same tracks), else in order of arrival. With ground truth in the recording, the "
        "recorded and the new tracks are scored side by side.",
    )
    p.add_argument("file", type=Path, help="the recording (.mcap or .jsonl)")
    p.add_argument("-o", "--output", type=Path, help="write the new tracks (.mcap or .jsonl)")
    p.add_argument(
        "--set", dest="overrides", metavar="KEY=VALUE", action="append", default=[],
        help="change a tracker setting, e.g. --set tracker.identity.enabled=false",
    )  # fmt: skip
    p.add_argument("--format", choices=("table", "json", "markdown"), default="table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Retrack, print what was done (and the scores); status 2 for a bad file or setting."""
    from openptrack_py.errors import ConfigError, WireFormatError
    from openptrack_py.eval.retrack import recorded_tracker_config, retrack

    if not args.file.is_file():
        print(f"openptrack retrack: no file {args.file}", file=sys.stderr)
        return EXIT_CONFIG
    progress = ProgressLine()
    start = [None]

    def show(t: float) -> None:
        start[0] = t if start[0] is None else start[0]
        progress.show(f"retrack {args.file.name}: {t - start[0]:7.1f} s of recording")

    output = args.output
    if output is not None and output.exists():
        print(f"openptrack retrack: {output} exists (not overwritten)", file=sys.stderr)
        return EXIT_CONFIG
    with tempfile.TemporaryDirectory() as tmp:
        scored = output or Path(tmp) / "retracked.mcap"  # scored, then thrown away
        try:
            config = recorded_tracker_config(args.file, args.overrides)
            result = retrack(args.file, config, scored, on_progress=show)
        except (ConfigError, WireFormatError) as exc:
            print(f"openptrack retrack: {exc}", file=sys.stderr)
            return EXIT_CONFIG
        finally:
            progress.done()
        scores = _scores(args.file, scored) if result.truth_frames else {}
    row = {
        "file": args.file.name,
        "mode": result.mode,
        "steps": result.steps,
        "identical": result.identical,
        "missing": result.missing,
        "first_step": result.first_step,
    }
    row.update(scores)
    columns = ["file", "mode", "steps", "identical", "missing", "first_step"]
    columns += [c for c in ("recorded_mota", "mota", "recorded_idf1", "idf1") if c in row]
    print_rows([row], columns, args.format)
    if result.stopped:
        print(f"openptrack retrack: {result.stopped}", file=sys.stderr)
    if result.first_step not in (None, 1):
        print(
            f"openptrack retrack: the recording starts at the tracker's step "
            f"{result.first_step}: what it took before is not in it, so its tracks cannot "
            "be reproduced exactly",
            file=sys.stderr,
        )
    if output is not None:
        print(f"wrote {output}", file=sys.stderr)
    return 0


def _scores(recording: Path, output: Path) -> dict[str, float]:
    """MOTA and IDF1 of the recorded and the new tracks (the recording has ground truth)."""
    from openptrack_py.eval.trackers import run_file_eval

    out: dict[str, float] = {}
    for prefix, path in (("recorded_", recording), ("", output)):
        try:
            metrics = run_file_eval(recording, tracks=path).metrics
        except Exception as exc:  # a recording without tracks is scored as nothing
            print(f"openptrack retrack: cannot score {path}: {exc}", file=sys.stderr)
            continue
        out[f"{prefix}mota"] = round(metrics.mota, 4)
        out[f"{prefix}idf1"] = round(metrics.idf1, 4)
    return out
