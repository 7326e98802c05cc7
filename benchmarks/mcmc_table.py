"""The childcare paper's MCMC tracker next to ours: accuracy and cost per batch.

``openptrack eval --tracker mcmc`` and the default tracker on ``classroom``, ``crowd``
and ``occlusions``, realistic profile, seeds 21-23 (the evaluation seeds), each
scenario's full length. Prints a Markdown table (means over the seeds) and the JSON rows::

    python -m benchmarks.mcmc_table
    python -m benchmarks.mcmc_table --seed 21 --duration 30   # quicker
    python -m benchmarks.mcmc_table --profile ideal --seed 21  # clean detections
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from openptrack_py.eval.trackers import run_eval

SCENARIOS = ("classroom", "crowd", "occlusions")
TRACKERS = ("ukf", "mcmc")
COLUMNS = ("mota", "idf1", "id_switches", "duplicates", "fp", "fn", "ms_per_batch")


def run(job: tuple[str, str, int, float | None, str]) -> dict[str, object]:
    scenario, tracker, seed, duration, profile = job
    result = run_eval(scenario, seed, duration_s=duration, tracker=tracker, profile=profile)
    m = result.metrics
    return {
        "scenario": scenario, "tracker": tracker, "seed": seed,
        "mota": round(m.mota, 4), "idf1": round(m.idf1, 4), "id_switches": m.id_switches,
        "duplicates": m.duplicates, "fp": m.fp, "fn": m.fn,
        "ms_per_batch": round(result.tracker_ms_per_batch or float("nan"), 3),
    }  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, action="append")
    parser.add_argument("--duration", type=float)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--profile", default="realistic", help="noise profile (ideal: a check)")
    args = parser.parse_args(argv)
    seeds = args.seed or [21, 22, 23]
    jobs = [
        (s, t, seed, args.duration, args.profile)
        for s in SCENARIOS for t in TRACKERS for seed in seeds
    ]  # fmt: skip
    with ProcessPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(run, jobs))
    for row in rows:
        print(json.dumps(row), file=sys.stderr)
    print("| scenario | tracker | " + " | ".join(COLUMNS) + " |")
    print("|---|---|" + "---|" * len(COLUMNS))
    for scenario in SCENARIOS:
        for tracker in TRACKERS:
            mine = [r for r in rows if r["scenario"] == scenario and r["tracker"] == tracker]
            cells = [f"{np.mean([r[c] for r in mine]):.3f}" for c in COLUMNS]
            name = "ours" if tracker == "ukf" else "MCMC (childcare paper)"
            print(f"| {scenario} | {name} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
