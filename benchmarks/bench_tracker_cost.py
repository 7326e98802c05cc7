"""Tracker cost per detection batch at 5, 20, 100 and 300 confirmed tracks.

Scene: ``n`` people standing on a square grid 1.5 m apart, all drifting slowly the same
way (0.3 m/s along x, 0.1 m/s along y) with a small individual sway (0.1 m, 4 s
period), so they stay well separated. One sensor at 30 Hz reports every person once
per batch, in shuffled order, with 3 cm Gaussian position noise, confidence 0.9 and a
reported range of 3 m (so every detection has the tracker's noise at 3 m, whatever its
position on the large grids), an image box and a 19-bin colour signature (each person's
own, with lighting noise). No clutter, no misses.

Ours: ``openptrack_py.tracking.build_tracker()`` with the default ``TrackerConfig``
(UKF, chi-square gate, GNN, lifecycle, robust track management), and, in the same run,
the plain tracker with robust track management off (``ROBUSTNESS_OFF``: what the
tracker cost before it; ``robust_over_plain`` is the ratio), and the default tracker with
the identity role on (``identity_over_off``: its cost over the default's; target <= 2 at
100 tracks). 150 warm-up batches confirm
every track (a track is confirmed once its person has moved 0.5 m), then
``Tracker.step`` is timed alone (batches are built beforehand) for 300 batches; each
step predicts, gates, assigns and updates all ``n`` tracks and builds the output
``TrackBatch``.

Baseline, same run: one filterpy 2 ``UnscentedKalmanFilter`` per person (Merwe sigma
points, alpha 1, beta 2, kappa 0, as ours; same Q and R as ours for this dt and range),
each detection handed to its own filter (no gating, no association, no lifecycle, no
output message): per batch, ``predict(dt)`` then ``update(z)`` for every filter, timed as
one loop. ``filterpy_over_ours`` is the filterpy loop's mean time over our whole step's
mean time.

Single thread: ``OMP_NUM_THREADS``, ``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS`` are set
to 1 at the top of this module, before numpy is imported. That only takes effect when
this module is the first to import numpy (``python -m benchmarks.bench_tracker_cost``);
``single_thread_env_effective`` in the output says whether it did (under
``benchmarks.run_all`` numpy is already loaded, so export the variables in the shell instead).

Prints one JSON line (milliseconds per batch: p50 and mean) with the targets:
<= 1 ms at 20 tracks, <= 5 ms at 100 tracks, identity on <= 2x off at 100 tracks.

Run from the repository root::

    python -m benchmarks.bench_tracker_cost [--batches N] [--counts N ...]
"""

# ruff: noqa: E402  (the thread variables must be set before numpy is imported)

from __future__ import annotations

import os
import sys

_NUMPY_PRELOADED = "numpy" in sys.modules
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse
import gc
import math
import time

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

from benchmarks.common import emit
from openptrack_py.config import ROBUSTNESS_OFF, TrackerConfig
from openptrack_py.messages import Detection, DetectionBatch
from openptrack_py.tracking import build_tracker
from openptrack_py.tracking.measurement import PositionMeasurement
from openptrack_py.tracking.motion import ConstantVelocity

COUNTS = (5, 20, 100, 300)
RATE_HZ = 30.0
SPACING_M = 1.5
RANGE_M = 3.0
NOISE_M = 0.03
WARMUP = 150
TARGETS_MS = {20: 1.0, 100: 5.0}
T0 = 1_767_225_600.0
SIGNATURE_BINS = 19
IDENTITY_TARGET = (100, 2.0)
"""Identity on costs at most this many times off at this many tracks."""


def scene(n: int, batches: int, seed: int = 0) -> tuple[list[DetectionBatch], np.ndarray]:
    """Batches of ``n`` grid people, and the ``(batches, n, 2)`` unshuffled detections."""
    rng = np.random.default_rng(seed)
    looks_rng = np.random.default_rng([seed, 1])  # apart, so positions stay as they were
    clothes = looks_rng.dirichlet(np.full(SIGNATURE_BINS, 0.3), n)
    side = math.ceil(math.sqrt(n))
    grid = SPACING_M * np.array([(i % side, i // side) for i in range(n)], dtype=float)
    phase = rng.uniform(0.0, 2 * math.pi, n)
    out, xy_all = [], np.zeros((batches, n, 2))
    for k in range(batches):
        t = k / RATE_HZ
        xy = grid + np.array([0.3 * t, 0.1 * t])
        xy[:, 0] += 0.1 * np.sin(2 * math.pi * t / 4.0 + phase)
        xy += rng.normal(0.0, NOISE_M, xy.shape)
        xy_all[k] = xy
        looks = clothes * looks_rng.gamma(20.0, 1 / 20.0, clothes.shape)
        looks = np.round(255 * looks / looks.sum(axis=1, keepdims=True)).astype(int).tolist()
        dets = [
            Detection(x=float(xy[i, 0]), y=float(xy[i, 1]), z=0.9, height=1.7, confidence=0.9,
                      distance=RANGE_M, bbox=(40 * (i % 16), 40 * (i // 16), 30, 120),
                      appearance=tuple(looks[i]))
            for i in rng.permutation(n)
        ]  # fmt: skip
        out.append(DetectionBatch("bench", k, T0 + t, "world", tuple(dets)))
    return out, xy_all


def time_ours(batches: list[DetectionBatch], cfg: TrackerConfig) -> dict[str, object]:
    tracker = build_tracker(cfg)
    for b in batches[:WARMUP]:
        out = tracker.step(b)
    confirmed_before = sum(tr.confirmed for tr in out.tracks)
    gc.collect()
    samples = []
    for b in batches[WARMUP:]:
        start = time.perf_counter()
        out = tracker.step(b)
        samples.append(time.perf_counter() - start)
    return {
        "samples": np.array(samples),
        "confirmed_after_warmup": confirmed_before,
        "confirmed_at_end": sum(tr.confirmed for tr in out.tracks),
        "tracks_started": out.max_id,
    }


def filterpy_bank(first: np.ndarray, cfg: TrackerConfig) -> list[UnscentedKalmanFilter]:
    dt = 1.0 / RATE_HZ
    q = ConstantVelocity(cfg.acceleration_variance).noise(np.array([dt]))[0]
    r = PositionMeasurement(cfg.measurement_sigma_m, cfg.measurement_sigma_per_m2).noise(
        np.array([RANGE_M])
    )[0]

    def fx(x: np.ndarray, dt: float) -> np.ndarray:
        return np.array([x[0] + dt * x[2], x[1] + dt * x[3], x[2], x[3]])

    def hx(x: np.ndarray) -> np.ndarray:
        return x[:2]

    bank = []
    for p in first:
        f = UnscentedKalmanFilter(
            dim_x=4,
            dim_z=2,
            dt=dt,
            hx=hx,
            fx=fx,
            points=MerweScaledSigmaPoints(4, alpha=1.0, beta=2.0, kappa=0.0),
        )
        f.x = np.array([p[0], p[1], 0.0, 0.0])
        v2 = cfg.initial_velocity_sigma_mps**2
        f.P = np.diag([r[0, 0], r[1, 1], v2, v2])
        f.Q = q.copy()
        f.R = r.copy()
        bank.append(f)
    return bank


def time_filterpy(xy_all: np.ndarray, cfg: TrackerConfig) -> np.ndarray:
    dt = 1.0 / RATE_HZ
    bank = filterpy_bank(xy_all[0], cfg)
    samples = []
    for k in range(1, len(xy_all)):
        start = time.perf_counter()
        for f, z in zip(bank, xy_all[k], strict=True):
            f.predict(dt=dt)
            f.update(z)
        if k >= WARMUP:
            samples.append(time.perf_counter() - start)
    return np.array(samples)


def stats(samples: np.ndarray) -> dict[str, float]:
    ms = 1e3 * np.asarray(samples)
    return {"p50_ms": round(float(np.median(ms)), 4), "mean_ms": round(float(ms.mean()), 4)}


def main(batches: int = 300, counts: tuple[int, ...] = COUNTS) -> dict[str, object]:
    cfg = TrackerConfig()
    per_count: dict[str, object] = {}
    meets: dict[str, bool] = {}
    for n in counts:
        stream, xy_all = scene(n, WARMUP + batches, seed=n)
        ours = time_ours(stream, cfg)
        plain = stats(time_ours(stream, TrackerConfig(**ROBUSTNESS_OFF))["samples"])
        ident = stats(time_ours(stream, TrackerConfig(identity={"enabled": True}))["samples"])
        fp = time_filterpy(xy_all, cfg)
        o, f = stats(ours["samples"]), stats(fp)
        per_count[str(n)] = {
            "ours": o,
            "plain": plain,
            "robust_over_plain": round(o["mean_ms"] / plain["mean_ms"], 2),
            "identity_on": ident,
            "identity_over_off": round(ident["mean_ms"] / o["mean_ms"], 2),
            "filterpy_loop": f,
            "filterpy_over_ours": round(f["mean_ms"] / o["mean_ms"], 2),
            "confirmed_after_warmup": ours["confirmed_after_warmup"],
            "confirmed_at_end": ours["confirmed_at_end"],
            "tracks_started": ours["tracks_started"],
        }
        if n in TARGETS_MS:
            meets[f"{n}_tracks_le_{TARGETS_MS[n]:g}_ms"] = o["p50_ms"] <= TARGETS_MS[n]
        if n == IDENTITY_TARGET[0]:
            key = f"identity_at_{n}_le_{IDENTITY_TARGET[1]:g}x"
            meets[key] = ident["mean_ms"] <= IDENTITY_TARGET[1] * o["mean_ms"]
    return emit(
        "tracker_cost",
        {
            "batches_timed": batches,
            "warmup_batches": WARMUP,
            "rate_hz": RATE_HZ,
            "single_thread_env_effective": not _NUMPY_PRELOADED,
            "tracks": per_count,
            "targets_p50_met": meets,
        },
    )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batches", type=int, default=300, help="timed batches per count")
    parser.add_argument("--counts", type=int, nargs="+", default=list(COUNTS))
    args = parser.parse_args()
    main(args.batches, tuple(args.counts))
