"""Two tracker settings on the same seeds: the paired differences and how sure they are.

On a scene of a dozen people, a change that moves one identity event moves IDF1 by
0.05-0.1 on that seed, whichever way the change points; three seeds cannot tell a better
tracker from a lucky draw. Run both settings on many seeds nobody has looked at and read
the differences seed by seed::

    python -m benchmarks.paired --scenario crowd --seeds 200-219 --duration 60 \\
        --set occlusion_aware_support=true
    python -m benchmarks.paired --scenario crowd --seeds 240-259 --duration 60 \\
        --point calibration=0.2 --set calibration_sigma_m=0.12 --set calibration_sigma_deg=2

Each seed runs as ``openptrack eval --scenario S --seed N --profile P [--set ...]`` once
with the base settings (``--base-set``, default none) and once with ``--set``; with
``--point AXIS=VALUE``, on the ``realistic`` profile made worse as the robustness sweep
makes it at that point (``benchmarks/sweep.py``). For every metric the summary gives
both means, the mean of the paired differences (``--set`` minus base) with a 95 %
bootstrap interval over seeds, and how many seeds got better, stayed equal and got
worse (for MOTA and IDF1 higher is better, for the counts lower), with the two-sided
sign test's p-value on those. The interval and the p-value say how far the seeds drawn
speak for seeds not drawn; they do not make the simulator any more real. Runs print as
JSON lines (``--json FILE`` keeps them); progress goes to stderr.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from contextlib import ExitStack
from pathlib import Path
from typing import NamedTuple

import numpy as np
from scipy.stats import binomtest

from openptrack_py.errors import ConfigError
from openptrack_py.eval.runner import format_markdown
from openptrack_py.eval.trackers import load_tracker_config, run_eval
from openptrack_py.sim import SCENARIO_NAMES

METRICS = {
    "mota": True,
    "idf1": True,
    "id_switches": False,
    "duplicates": False,
    "fp": False,
    "fn": False,
}
"""The metrics compared, each with whether higher is better."""
RESAMPLES = 10_000
"""Bootstrap resamples of the seeds."""


class Job(NamedTuple):
    """One run: a seed of a scenario with one variant's settings."""

    scenario: str
    seed: int
    profile: str
    duration_s: float | None  # None: the scenario's own
    variant: str  # "base" or "other"
    overrides: tuple[str, ...]
    point: tuple[str, float] | None = None  # a robustness sweep axis and its value


def parse_seeds(text: str) -> list[int]:
    """``"200-219"``, ``"3,5,8"`` or a mix (``"3,10-12"``) as a sorted list of seeds.

    Raises
    ------
    ValueError
        Naming the part that is not a seed or a range of them.
    """
    seeds: set[int] = set()
    for part in text.split(","):
        lo, sep, hi = part.strip().partition("-")
        try:
            first, last = int(lo), int(hi if sep else lo)
        except ValueError:
            raise ValueError(f"seeds: {part!r} is not a seed or a range like 200-219") from None
        if first < 0 or last < first:
            raise ValueError(f"seeds: {part!r} is not a range of seeds >= 0, low to high")
        seeds.update(range(first, last + 1))
    return sorted(seeds)


def paired_summary(
    base: Sequence[float], other: Sequence[float], higher_is_better: bool, rng_seed: int = 0
) -> dict[str, float | int]:
    """Means, the mean paired difference ``other - base`` with its 95 % interval, the sign test.

    The interval is the percentile bootstrap over the pairs (:data:`RESAMPLES` resamples,
    drawn from ``rng_seed``: the same figures every run); ties do not enter the sign
    test.

    Raises
    ------
    ValueError
        If the two sequences differ in length or are empty.
    """
    a, b = np.asarray(base, dtype=float), np.asarray(other, dtype=float)
    if a.shape != b.shape or a.ndim != 1 or not len(a):
        raise ValueError(f"paired: need two equally long runs of seeds, got {a.shape}, {b.shape}")
    diff = b - a
    picks = np.random.default_rng(rng_seed).integers(0, len(diff), (RESAMPLES, len(diff)))
    low, high = np.percentile(diff[picks].mean(axis=1), [2.5, 97.5])
    better = diff > 0 if higher_is_better else diff < 0
    worse = diff < 0 if higher_is_better else diff > 0
    wins, losses = int(better.sum()), int(worse.sum())
    p = binomtest(wins, wins + losses, 0.5).pvalue if wins + losses else 1.0
    return {
        "base": float(a.mean()),
        "other": float(b.mean()),
        "diff": float(diff.mean()),
        "ci_low": float(low),
        "ci_high": float(high),
        "better": wins,
        "equal": len(diff) - wins - losses,
        "worse": losses,
        "sign_p": float(p),
    }


def run(job: Job) -> dict[str, object]:
    """One seed of one scenario with one variant's settings.

    With a sweep ``point``, the ``realistic`` profile made worse along that axis of the
    robustness sweep (:data:`benchmarks.sweep.AXES`) as the sweep does.
    """
    if job.point is None:
        result = run_eval(
            job.scenario, job.seed, duration_s=job.duration_s, profile=job.profile,
            overrides=job.overrides,
        )  # fmt: skip
    else:
        from benchmarks.sweep import point_scenario

        duration_s = -1.0 if job.duration_s is None else job.duration_s  # -1: its own
        built = point_scenario(job.scenario, job.seed, duration_s, *job.point)
        result = run_eval(built, overrides=job.overrides)
    row: dict[str, object] = {"scenario": job.scenario, "seed": job.seed, "variant": job.variant}
    row.update({k: v for k, v in result.metrics.to_dict().items() if k in METRICS})
    return row


def summarise(rows: list[dict[str, object]]) -> list[dict[str, object]]:
    """One summary row per scenario and metric, over the seeds both variants ran."""
    out = []
    for scenario in dict.fromkeys(str(r["scenario"]) for r in rows):
        runs = {(r["variant"], r["seed"]): r for r in rows if r["scenario"] == scenario}
        seeds = sorted({s for v, s in runs if v == "base"} & {s for v, s in runs if v == "other"})
        for metric, higher in METRICS.items():
            base = [float(runs["base", s][metric]) for s in seeds]  # type: ignore[arg-type]
            other = [float(runs["other", s][metric]) for s in seeds]  # type: ignore[arg-type]
            summary = paired_summary(base, other, higher)
            out.append({"scenario": scenario, "metric": metric, "seeds": len(seeds), **summary})
    return out


def _rounded(row: dict[str, object]) -> dict[str, object]:
    return {k: round(v, 4) if isinstance(v, float) else v for k, v in row.items()}


def _arguments(argv: list[str] | None) -> tuple[argparse.Namespace, list[Job]]:
    """The command line, checked before any run (each error names what is wrong)."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scenario", action="append", required=True)
    parser.add_argument("--seeds", required=True, help="e.g. 200-219 or 3,5,8")
    parser.add_argument("--profile", default="realistic")
    parser.add_argument("--duration", type=float, help="seconds (default: the scenario's own)")
    parser.add_argument(
        "--point", metavar="AXIS=VALUE", help="a robustness sweep point, e.g. calibration=0.2"
    )
    for flag, dest in (("--set", "other"), ("--base-set", "base")):
        parser.add_argument(flag, dest=dest, action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--jobs", type=int, default=2, help="processes (1: this one)")
    parser.add_argument("--json", type=Path, help="also write the runs here, as JSON lines")
    args = parser.parse_args(argv)
    try:
        seeds = parse_seeds(args.seeds)
        point = None if args.point is None else parse_point(args.point)
    except ValueError as exc:
        parser.error(str(exc))
    if point is not None and args.profile != "realistic":
        parser.error("paired: a sweep --point makes the realistic profile worse: no --profile")
    if args.other == args.base:
        parser.error("paired: --set and --base-set give the same settings: nothing to compare")
    unknown = [s for s in args.scenario if s not in SCENARIO_NAMES]
    if unknown:
        allowed = ", ".join(SCENARIO_NAMES)
        parser.error(f"paired: unknown scenario {unknown[0]!r} (allowed: {allowed})")
    try:  # refused here, not once per run in the workers
        load_tracker_config(None, args.base)
        load_tracker_config(None, args.other)
    except ConfigError as exc:
        parser.error(str(exc))
    jobs = [
        Job(scenario, seed, args.profile, args.duration, variant, tuple(overrides), point)
        for scenario in args.scenario
        for seed in seeds
        for variant, overrides in (("base", args.base), ("other", args.other))
    ]
    return args, jobs


def parse_point(text: str) -> tuple[str, float]:
    """``"calibration=0.2"`` as a robustness sweep axis and value.

    Raises
    ------
    ValueError
        Naming the allowed axes, or the value that is not a number.
    """
    from benchmarks.sweep import AXES

    axis, _, value = text.partition("=")
    if axis not in AXES:
        raise ValueError(f"point: unknown axis {axis!r} (allowed: {', '.join(AXES)})")
    try:
        return axis, float(value)
    except ValueError:
        raise ValueError(f"point: {value!r} is not a number (e.g. {axis}=0.2)") from None


def main(argv: list[str] | None = None) -> None:
    args, jobs = _arguments(argv)
    rows = []
    with ExitStack() as stack:
        if args.jobs <= 1:
            results = map(run, jobs)
        else:
            results = stack.enter_context(ProcessPoolExecutor(args.jobs)).map(run, jobs)
        for i, row in enumerate(results, 1):
            rows.append(row)
            print(json.dumps(row), flush=True)
            print(f"paired: {i}/{len(jobs)}", file=sys.stderr, flush=True)
    if args.json is not None:
        args.json.write_text("".join(json.dumps(r) + "\n" for r in rows))
    columns = ["scenario", "metric", "seeds", "base", "other", "diff", "ci_low", "ci_high"]
    columns += ["better", "equal", "worse", "sign_p"]
    print(format_markdown([_rounded(r) for r in summarise(rows)], columns))


if __name__ == "__main__":
    main()
