"""The childcare paper's classroom figures, from our pipeline, checked against ground truth.

The ``classroom`` scenario (a teacher and 15-20 children playing the drum game, realistic
profile) runs through the default tracker; the analytics run on each person's tracked
positions and on their true ones (:mod:`openptrack_py.eval.analytics_check`). Draws the
kinds of figures of the childcare tracking paper (Zhang et al.): trajectories of the
teacher and two children (its Fig. 7), their motion areas and momentum (Fig. 8), the
relative distances between the teacher and three children and between one child and two
others (Fig. 9), tracked against true; writes the full HTML report of the tracked
analysis; prints JSON of the errors::

    python -m benchmarks.classroom_analytics            # seed 41, the whole scenario
    python -m benchmarks.classroom_analytics --out docs/classroom
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from openptrack_py.analytics.report import write_report
from openptrack_py.eval.analytics_check import AnalyticsCheck, check_analytics
from openptrack_py.sim.scenarios import build_scenario

ROOT = Path(__file__).resolve().parent.parent


def _people(check: AnalyticsCheck) -> tuple[int, list[int]]:
    """The teacher and the children, children by time seen."""
    teacher = next(k for k, kind in check.kinds.items() if kind == "adult")
    children = [k for k in check.truth.people if check.kinds.get(k) == "child"]
    children.sort(key=lambda k: -check.truth.people[k].seen_s)
    return teacher, children


def figures(check: AnalyticsCheck, out: Path) -> dict[str, object]:
    """Draw the three figures; return the paper-style numbers, tracked and true."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    teacher, children = _people(check)
    chosen = [teacher, *children[:2]]
    names = {teacher: "teacher", children[0]: "child 1", children[1]: "child 2"}
    if len(children) > 2:
        names[children[2]] = "child 3"
    colours = ["tab:red", "tab:blue", "tab:green", "tab:purple"]
    start = check.truth.start

    fig, ax = plt.subplots(figsize=(7, 6))
    for key, colour in zip(chosen, colours, strict=False):
        true, tracked = check.truth.people[key].path, check.tracked.people[key].path
        ax.plot(
            true[:, 1], true[:, 2], color=colour, lw=2, alpha=0.35, label=f"{names[key]} (true)"
        )
        ax.plot(tracked[:, 1], tracked[:, 2], color=colour, lw=1, label=f"{names[key]} (tracked)")
    ax.set_aspect("equal")
    ax.set_title("trajectories during the drum game")
    ax.legend(fontsize=7)
    fig.savefig(out / "classroom_trajectories.png", dpi=100, bbox_inches="tight")
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    for key, colour in zip(chosen, colours, strict=False):
        for analysis, style in ((check.truth, ":"), (check.tracked, "-")):
            x0, y0, x1, y1 = analysis.people[key].bbox
            axes[0].add_patch(
                Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec=colour, ls=style)
            )
            momentum = np.array(analysis.people[key].momentum)
            label = f"{names[key]} ({'true' if style == ':' else 'tracked'})"
            axes[1].plot(
                momentum[:, 0] - start, momentum[:, 1], color=colour, ls=style, label=label
            )
    axes[0].autoscale()
    axes[0].set_aspect("equal")
    axes[0].set_title("motion areas (bounding rectangles; dotted: true)")
    axes[1].set_title("momentum: trajectory length so far")
    axes[1].set_xlabel("time (s)")
    axes[1].set_ylabel("m")
    axes[1].legend(fontsize=7)
    fig.savefig(out / "classroom_areas_momentum.png", dpi=100, bbox_inches="tight")
    plt.close(fig)

    pairs_a = [(teacher, c) for c in children[:3]]
    pairs_b = [(children[2], c) for c in children[:2]] if len(children) > 2 else []
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    rows = []
    for ax, pairs in ((axes[0], pairs_a), (axes[1], pairs_b)):
        for (a, b), colour in zip(pairs, colours, strict=False):
            key = (min(a, b), max(a, b))
            true, tracked = check.truth.pairs[key], check.tracked.pairs[key]
            label = f"{names[a]} - {names[b]}"
            ax.plot(true.series[:, 0] - start, true.series[:, 1], color=colour, alpha=0.35, lw=2)
            ax.plot(tracked.series[:, 0] - start, tracked.series[:, 1], color=colour, lw=1,
                    label=f"{label}: {tracked.mean_m:.2f} +- {tracked.std_m:.2f} m")  # fmt: skip
            rows.append({
                "pair": label,
                "tracked_mean_m": round(tracked.mean_m, 3), "true_mean_m": round(true.mean_m, 3),
                "tracked_std_m": round(tracked.std_m, 3), "true_std_m": round(true.std_m, 3),
            })  # fmt: skip
        ax.set_xlabel("time (s)")
        ax.set_ylabel("distance (m)")
        ax.legend(fontsize=7)
    axes[0].set_title("relative distance to the teacher (thick: true)")
    axes[1].set_title("relative distance to child 3 (thick: true)")
    fig.savefig(out / "classroom_distances.png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    people = [
        {
            "person": names[k],
            "tracked_length_m": round(check.tracked.people[k].length_m, 2),
            "true_length_m": round(check.truth.people[k].length_m, 2),
            "tracked_area_m2": round(check.tracked.people[k].bbox_area_m2, 2),
            "true_area_m2": round(check.truth.people[k].bbox_area_m2, 2),
        }
        for k in chosen
    ]
    return {"people": people, "distances": rows}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=41)
    parser.add_argument("--duration", type=float, default=-1.0, help="seconds (scenario's own)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "classroom")
    args = parser.parse_args(argv)
    scenario = build_scenario(
        "classroom", seed=args.seed, duration_s=args.duration, profile="realistic"
    )
    check = check_analytics(scenario)
    args.out.mkdir(parents=True, exist_ok=True)
    numbers = figures(check, args.out)
    write_report(
        check.tracked, args.out / "classroom_report.html",
        title="classroom (simulated drum game), tracked",
        source=f"python -m benchmarks.classroom_analytics --seed {args.seed}",
    )  # fmt: skip
    lengths = np.array(list(check.length_errors().values()))
    areas = np.array(list(check.area_errors().values()))
    distances = np.array(list(check.distance_errors().values()))
    m = check.result.metrics
    summary = {
        "benchmark": "classroom_analytics",
        "seed": args.seed,
        "duration_s": scenario.duration_s,
        "tracking": {"mota": round(m.mota, 4), "idf1": round(m.idf1, 4)},
        "people": len(lengths),
        "length_error": {
            "mean": round(float(lengths.mean()), 4),
            "max_abs": round(float(np.abs(lengths).max()), 4),
            "within_5_percent": int((np.abs(lengths) <= 0.05).sum()),
        },
        "area_error_max_abs": round(float(np.abs(areas).max()), 4),
        "mean_distance_error_m": {
            "pairs": len(distances),
            "max_abs": round(float(np.abs(distances).max()), 4),
            "mean": round(float(distances.mean()), 4),
        },
        **numbers,
    }
    (args.out / "classroom_analytics.json").write_text(json.dumps(summary, indent=1) + "\n")
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
