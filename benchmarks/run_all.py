"""Run every benchmark; print each one's JSON line, then a combined JSON document.

The combined document is also written to ``benchmarks/results/latest.json``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

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


def main() -> None:
    results = {
        "machine": machine(),
        "codec": bench_codec.main(),
        "zenoh_latency": bench_zenoh_latency.main(),
        "end_to_end": bench_end_to_end.main(),
        "simulator": bench_sim.main(),
        "tracker_cost": bench_tracker_cost.main(),
        "detector": bench_detector.main(),
        "stonesoup": bench_stonesoup.main(),
    }
    out = Path(__file__).resolve().parent / "results" / "latest.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(results, indent=1))
    print(json.dumps(results))


if __name__ == "__main__":
    main()
