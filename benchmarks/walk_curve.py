"""How long to walk: calibration from one walking person against the walk's length.

For each scenario and seed, one person walks through the room for each duration; the
sensors are calibrated from the walk with no checkerboard and no pose guess
(:func:`openptrack_py.calibration.walk.calibrate_walk`, the first sensor as the
reference at its true pose), and every other sensor's estimate is compared with the
truth: position, heading and clock offset. Two noise profiles: ``realistic``, and the
same without its persistent detector error (``correlated_sigma_m = 0``: the error one
sensor's detector makes on one person for about a second, independently of the other
sensors'), which shows what limits the realistic figures.

Prints one JSON line per profile and duration (sensors within 5 cm, 1 degree and 10 ms,
sessions with every sensor within all three, walks refused as covering too little,
medians and worst errors), then writes the rows to ``--out`` and the curves to
``--plot``. A refused walk counts as a session not within; its sensors count in no
estimate (the shares are of the sensors of the walks calibrated).

Run from the repository root (about 8 minutes on 2 cores)::

    python -m benchmarks.walk_curve --out docs/walk_curve.json --plot docs/walk_curve.png
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from openptrack_py.calibration.walk import calibrate_walk
from openptrack_py.errors import CalibrationError
from openptrack_py.eval.walk import simulate_walk
from openptrack_py.sim.profiles import REALISTIC

SCENARIOS = ("crowd", "installation")
SEEDS = tuple(range(61, 69))
"""Never used while the walk calibration was developed."""
DURATIONS_S = (30.0, 60.0, 90.0, 120.0, 180.0)
POSITION_M, YAW_DEG, OFFSET_S = 0.05, 1.0, 0.010
"""The acceptance figures: every sensor within 5 cm and 1 degree, clocks within 10 ms."""
PROFILES = {
    "realistic": REALISTIC,
    "realistic, no persistent error": dataclasses.replace(
        REALISTIC, name="realistic-no-persistent", correlated_sigma_m=0.0
    ),
}


def one_session(job: tuple[str, str, int, float]) -> dict[str, object]:
    """Errors of every non-reference sensor of one walk."""
    profile, scenario, seed, duration = job
    session = simulate_walk(scenario, seed=seed, duration_s=duration, profile=PROFILES[profile])
    ref = session.tracks[0].sensor_id
    head = {"profile": profile, "scenario": scenario, "seed": seed, "duration_s": duration}
    try:
        result = calibrate_walk(
            session.tracks, reference=ref, reference_pose=session.true_poses[ref]
        )
    except CalibrationError as exc:  # a walk too short to cover the views: refused
        return {**head, "refused": str(exc), "sensors": []}
    offsets = session.relative_offsets(ref)
    sensors = []
    for sid, truth in session.true_poses.items():
        if sid == ref:
            continue
        dist, yaw = result.poses[sid].error_to(truth)
        spread = result.spread[sid]
        sensors.append(
            {
                "sensor": sid,
                "position_m": float(dist),
                "yaw_deg": float(yaw),
                "offset_s": float(abs(result.clock_offsets_s[sid] - offsets[sid])),
                "spread_m": spread.position_m,
                "spread_deg": spread.yaw_deg,
                "spread_s": spread.clock_s,
            }
        )
    return {**head, "sensors": sensors}


def _spread_shares(est: list[dict[str, float]]) -> dict[str, float]:
    """Share of errors within 1 and 3 times the spread between the walk's halves.

    Where the spread is the error's standard deviation, an error is within 1 times one
    draw of it half the time and within 3 times about four times in five (the ratio of
    two independent normal draws; nine in ten for the position, a ratio of two distances
    in the plane).
    """
    out: dict[str, float] = {}
    for key, err, spr in (
        ("position", "position_m", "spread_m"),
        ("heading", "yaw_deg", "spread_deg"),
        ("clock", "offset_s", "spread_s"),
    ):
        ratio = np.array([s[err] / max(s[spr], 1e-12) for s in est])
        out[f"{key}_within_spread"] = round(float((ratio <= 1).mean()), 2)
        out[f"{key}_within_3_spreads"] = round(float((ratio <= 3).mean()), 2)
    return out


def summarise(rows: list[dict[str, object]]) -> list[dict[str, object]]:
    """Per profile and duration: counts within the acceptance figures, medians, worst."""
    out = []
    for profile in PROFILES:
        for duration in sorted({float(r["duration_s"]) for r in rows}):  # type: ignore[arg-type]
            mine = [r for r in rows if r["profile"] == profile and r["duration_s"] == duration]
            est = [s for r in mine for s in r["sensors"]]  # type: ignore[attr-defined]
            refused = sum("refused" in r for r in mine)
            if not est:
                continue
            pos = np.array([s["position_m"] for s in est])
            yaw = np.array([s["yaw_deg"] for s in est])
            off = np.array([s["offset_s"] for s in est])
            every = sum(
                all(
                    s["position_m"] <= POSITION_M
                    and s["yaw_deg"] <= YAW_DEG
                    and s["offset_s"] <= OFFSET_S
                    for s in r["sensors"]  # type: ignore[attr-defined]
                )
                for r in mine
                if "refused" not in r
            )
            out.append(
                {
                    "profile": profile,
                    "duration_s": duration,
                    "estimates": len(est),
                    "sessions": len(mine),
                    "refused": refused,
                    "within_5cm": int((pos <= POSITION_M).sum()),
                    "within_1deg": int((yaw <= YAW_DEG).sum()),
                    "within_10ms": int((off <= OFFSET_S).sum()),
                    "sessions_all_within": int(every),
                    "median_cm": round(float(np.median(pos)) * 100, 2),
                    "worst_cm": round(float(pos.max()) * 100, 2),
                    "median_deg": round(float(np.median(yaw)), 3),
                    "worst_deg": round(float(yaw.max()), 3),
                    "median_ms": round(float(np.median(off)) * 1000, 1),
                    "worst_ms": round(float(off.max()) * 1000, 1),
                    **_spread_shares(est),
                }
            )
    return out


def plot(summary: list[dict[str, object]], path: Path) -> None:
    """Share of estimates within each acceptance figure against the walk's length."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(15, 3.6), sharey=True)
    panels = (
        ("within_5cm", "estimates", "position within 5 cm"),
        ("within_1deg", "estimates", "heading within 1°"),
        ("within_10ms", "estimates", "clock within 10 ms"),
        ("sessions_all_within", "sessions", "sessions with every sensor\nwithin all three"),
    )
    for ax, (key, total, title) in zip(axes, panels, strict=True):
        for profile, style in zip(PROFILES, ("o-", "s--"), strict=True):
            rows = [s for s in summary if s["profile"] == profile]
            x = [s["duration_s"] for s in rows]
            y = [100.0 * s[key] / s[total] for s in rows]  # type: ignore[operator]
            ax.plot(x, y, style, label=profile)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("walk, seconds")
        ax.set_ylim(0, 105)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("%")
    axes[0].legend(fontsize=8, loc="lower right")
    fig.suptitle(
        "Calibration from one walking person, no checkerboard: 3 Kinect v2, "
        f"{len(SCENARIOS)} rooms x {len(SEEDS)} seeds",
        fontsize=11,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Run the sessions, print the summary lines, write the rows and the plot."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--durations", type=float, nargs="+", default=list(DURATIONS_S))
    parser.add_argument("--seeds", type=int, nargs="+", default=list(SEEDS))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, help="write the rows and summary as JSON")
    parser.add_argument("--plot", type=Path, help="write the curves as PNG")
    args = parser.parse_args(argv)
    jobs = [
        (profile, scenario, seed, duration)
        for profile in PROFILES
        for duration in args.durations
        for scenario in SCENARIOS
        for seed in args.seeds
    ]
    rows = []
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        for n, row in enumerate(pool.map(one_session, jobs), 1):
            rows.append(row)
            print(f"\r{n}/{len(jobs)} walks", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    summary = summarise(rows)
    for line in summary:
        print(json.dumps(line))
    if args.out is not None:
        args.out.write_text(json.dumps({"summary": summary, "rows": rows}, indent=1) + "\n")
    if args.plot is not None:
        plot(summary, args.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
