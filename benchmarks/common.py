"""Helpers shared by the benchmark scripts: percentiles, timing, JSON output."""

from __future__ import annotations

import json
import platform
import sys
import time
from collections.abc import Callable

import numpy as np


def percentiles(samples: list[float] | np.ndarray, scale: float = 1.0) -> dict[str, float]:
    """p50/p90/p99/max of ``samples`` times ``scale``, rounded."""
    a = np.asarray(samples, dtype=float) * scale
    return {
        "p50": round(float(np.percentile(a, 50)), 3),
        "p90": round(float(np.percentile(a, 90)), 3),
        "p99": round(float(np.percentile(a, 99)), 3),
        "max": round(float(a.max()), 3),
        "n": len(a),
    }


def per_call_us(fn: Callable[[], object], repeat: int = 7, number: int = 2000) -> float:
    """Best-of-``repeat`` mean time of ``fn`` in microseconds (``number`` calls each)."""
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        for _ in range(number):
            fn()
        best = min(best, (time.perf_counter() - start) / number)
    return round(best * 1e6, 3)


def machine() -> dict[str, object]:
    """Where the figures were measured."""
    return {"python": sys.version.split()[0], "platform": platform.platform()}


def emit(name: str, figures: dict[str, object]) -> dict[str, object]:
    """Print one benchmark's figures as a JSON line and return them."""
    out = {"benchmark": name, **figures}
    print(json.dumps(out), flush=True)
    return out
