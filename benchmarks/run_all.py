"""Run every benchmark; print each one's JSON line, then a combined JSON document.

The combined document is also written to ``benchmarks/results/latest.json``. The
benchmarks run one after another in this process (about 8 minutes on 2 cores); ``make
bench`` runs this with the BLAS/OpenMP thread variables set to 1.

Run from the repository root::

    python -m benchmarks.run_all [--only NAME ...]
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path

from benchmarks import (
    bench_codec,
    bench_detector,
    bench_end_to_end,
    bench_sim,
    bench_stonesoup,
    bench_tracker_cost,
    bench_zenoh_latency,
)
from benchmarks.common import machine

BENCHMARKS: dict[str, Callable[[], dict[str, object]]] = {
    "codec": bench_codec.main,
    "zenoh_latency": bench_zenoh_latency.main,
    "end_to_end": bench_end_to_end.main,
    "simulator": bench_sim.main,
    "tracker_cost": bench_tracker_cost.main,
    "detector": bench_detector.main,
    "stonesoup": bench_stonesoup.main,
}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--only",
        nargs="+",
        choices=list(BENCHMARKS),
        metavar="NAME",
        help=f"run only these ({', '.join(BENCHMARKS)}); default: all",
    )
    args = parser.parse_args(argv)
    names = [n for n in BENCHMARKS if args.only is None or n in args.only]
    results: dict[str, object] = {"machine": machine()}
    for name in names:
        results[name] = BENCHMARKS[name]()
    out = Path(__file__).resolve().parent / "results" / "latest.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(results, indent=1))
    print(json.dumps(results))


if __name__ == "__main__":
    main()
