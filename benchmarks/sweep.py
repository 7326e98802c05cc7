"""The robustness sweep: how tracking degrades as the detections get worse.

Starting from the ``realistic`` simulator profile on ``crowd`` (7 people, 3 Kinect v2),
one thing at a time is made worse, and every tracker runs on the very same detections:

* **centroid noise**: every centroid error term multiplied by 1-4
  (:meth:`~openptrack_py.sim.profiles.NoiseProfile.scaled`);
* **calibration error**: every sensor's pose off by 0-20 cm, with 15 degrees of yaw
  error per metre (1.5 degrees at 10 cm, 3 at 20: the OpenPTrack paper's range before
  refinement);
* **false positives**: 0.03-1 transient false positives per Kinect v2 frame with
  confidence up to 0.8, on top of the profile's static decoys.

Trackers: ``ours`` (the default ``TrackerConfig``), ``identity`` (the same with the
identity role on, ``identity.enabled=true``), ``plain`` (the same tracker with
robust track management off, ``ROBUSTNESS_OFF``), ``stonesoup`` (Stone Soup configured
as our model, :mod:`benchmarks.bench_stonesoup`; first seed only and 30 s, see
:data:`STONESOUP_BUDGET`) and ``norfair`` (plain norfair on floor
points, :mod:`benchmarks.norfair_runner`, in its own virtual environment because it pins
numpy < 2: ``--norfair-python``, or ``--make-norfair-env`` to create ``.venv-norfair``;
left out, and said so, when neither is there).

Prints one JSON line per run and a table, writes ``docs/robustness_sweep.json`` and the
curves ``docs/robustness_sweep.png``::

    python -m benchmarks.sweep --make-norfair-env     # about 40 minutes on 2 cores
    python -m benchmarks.sweep --quick                # 20 s runs, one seed, no PNG
    python -m benchmarks.sweep --trackers ours --merge  # re-run one tracker's rows only

The seeds (11 and 12) were not used while the tracker was developed.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from openptrack_py.config import ROBUSTNESS_OFF, TrackerConfig
from openptrack_py.eval.runner import Hypotheses, HypothesisFeed, evaluate
from openptrack_py.eval.trackers import load_tracker_config, tracking_feed
from openptrack_py.sim.profiles import REALISTIC, NoiseProfile
from openptrack_py.sim.scenarios import Scenario, build_scenario
from openptrack_py.sim.simulator import SensorFrame, TruthFrame

ROOT = Path(__file__).resolve().parent.parent
NORFAIR_ENV = ROOT / ".venv-norfair"
SEEDS = (11, 12)
SCENARIO = "crowd"
DURATION_S = 60.0
YAW_DEG_PER_M = 15.0
"""Yaw error that goes with a calibration offset, degrees per metre."""


@dataclass(frozen=True)
class Axis:
    """One direction of the sweep: a label and how a value changes the profile."""

    label: str
    values: tuple[float, ...]
    apply: Callable[[NoiseProfile, float], NoiseProfile]


AXES: dict[str, Axis] = {
    "noise": Axis(
        "centroid noise (x realistic)", (1.0, 2.0, 3.0, 4.0), lambda p, v: p.scaled(noise=v)
    ),
    "calibration": Axis(
        "calibration error (m, and 15 deg/m of yaw)",
        (0.0, 0.05, 0.10, 0.20),
        lambda p, v: p.with_calibration_error(v, YAW_DEG_PER_M * v),
    ),
    "false_positives": Axis(
        "false positives per frame (confidence <= 0.8)",
        (0.03, 0.1, 0.3, 1.0),
        lambda p, v: p.with_false_positives(v, 0.8),
    ),
}
TRACKERS = ("ours", "identity", "plain", "stonesoup", "norfair")
LOOKS = {
    "ours": ("o-", "ours"),
    "identity": ("v-", "ours, identity on"),
    "plain": ("s--", "ours, robustness off"),
    "stonesoup": ("^-.", "stonesoup"),
    "norfair": ("d:", "norfair"),
}
"""How each tracker's curve is drawn: line style and legend label."""
STONESOUP_BUDGET = (1, 30.0)
"""Stone Soup runs on the first seed only, for 30 s: its cost grows with the number of
tracks, which false positives multiply (minutes per run at one false positive per frame)."""


@dataclass
class NorfairFeed:
    """norfair in a child process of its own environment, fed one line per batch."""

    python: str
    stale_after_s: float = 1.0
    _latest: tuple[np.ndarray, np.ndarray] | None = None
    _latest_true_time: float = -float("inf")
    _proc: subprocess.Popen[str] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        runner = Path(__file__).with_name("norfair_runner.py")
        self._proc = subprocess.Popen(
            [self.python, str(runner)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
        )

    def on_sensor_frame(self, frame: SensorFrame) -> None:
        """Send the batch, read norfair's tracks after it."""
        assert self._proc is not None and self._proc.stdin and self._proc.stdout
        dets = [[d.x, d.y, d.confidence] for d in frame.batch.detections]
        self._proc.stdin.write(json.dumps({"t": frame.batch.stamp, "dets": dets}) + "\n")
        self._proc.stdin.flush()
        out = json.loads(self._proc.stdout.readline())
        if frame.capture_time >= self._latest_true_time:
            rows = np.array(out["xy"], dtype=float).reshape(-1, 4)
            self._latest = (np.array(out["ids"], dtype=np.int64), rows)
            self._latest_true_time = frame.capture_time

    def on_truth_frame(self, frame: TruthFrame) -> None:
        """norfair does not look at the truth."""

    def hypotheses_at(self, t: float) -> Hypotheses | None:
        """Latest tracks extrapolated to ``t``."""
        if self._latest is None:
            return None
        ids, rows = self._latest
        return Hypotheses.extrapolated(ids, rows, self._latest_true_time, t, self.stale_after_s)

    def close(self) -> None:
        """End the child process."""
        if self._proc is not None and self._proc.stdin:
            self._proc.stdin.close()
            self._proc.wait(timeout=30)


def _feed(
    tracker: str, norfair_python: str | None, overrides: tuple[str, ...] = ()
) -> HypothesisFeed:
    if tracker == "ours":
        return tracking_feed(load_tracker_config(None, overrides))
    if tracker == "identity":
        return tracking_feed(load_tracker_config(None, ("identity.enabled=true", *overrides)))
    if tracker == "plain":
        return tracking_feed(TrackerConfig(**ROBUSTNESS_OFF))
    if tracker == "stonesoup":
        from benchmarks.bench_stonesoup import StoneSoupFeed

        return StoneSoupFeed(TrackerConfig())
    if tracker == "norfair" and norfair_python:
        return NorfairFeed(norfair_python)
    raise ValueError(f"sweep: unknown tracker {tracker!r}")


def point_scenario(name: str, seed: int, duration_s: float, axis: str, value: float) -> Scenario:
    """Scenario ``name`` on the ``realistic`` profile made worse to ``value`` along ``axis``."""
    profile = AXES[axis].apply(REALISTIC, value)
    return build_scenario(name, seed=seed, duration_s=duration_s, profile=profile)


def run_point(
    job: tuple[str, float, str, int, float, str | None, tuple[str, ...]],
) -> dict[str, object]:
    """One tracker on one seed at one point of one axis (``ours`` with its overrides)."""
    axis, value, tracker, seed, duration_s, norfair_python, overrides = job
    scenario = point_scenario(SCENARIO, seed, duration_s, axis, value)
    feed = _feed(tracker, norfair_python, overrides)
    start = time.perf_counter()
    try:
        result = evaluate(scenario, feed)
    finally:
        if isinstance(feed, NorfairFeed):
            feed.close()
    m = result.metrics
    return {
        "axis": axis,
        "value": value,
        "tracker": tracker,
        "seed": seed,
        "mota": round(m.mota, 4),
        "idf1": round(m.idf1, 4),
        "id_switches": m.id_switches,
        "duplicates": m.duplicates,
        "fp": m.fp,
        "fn": m.fn,
        "wall_s": round(time.perf_counter() - start, 1),
    }


def make_norfair_env(path: Path = NORFAIR_ENV) -> str:
    """Create norfair's own virtual environment (once) and return its Python."""
    python = path / "bin" / "python"
    if not python.exists():
        print(f"sweep: creating {path} with norfair", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "venv", str(path)], check=True)
        subprocess.run([str(python), "-m", "pip", "install", "-q", "norfair"], check=True)
    return str(python)


def summarise(rows: list[dict[str, object]]) -> dict[str, dict[str, list[list[float]]]]:
    """Per axis and tracker, ``[value, mean MOTA, mean IDF1, min MOTA]`` per point."""
    out: dict[str, dict[str, list[list[float]]]] = {}
    for axis, spec in AXES.items():
        for tracker in sorted({str(r["tracker"]) for r in rows}):
            points = []
            for v in spec.values:
                sel = [r for r in rows if r["axis"] == axis and r["tracker"] == tracker]
                sel = [r for r in sel if r["value"] == v]
                if sel:
                    mota = [float(r["mota"]) for r in sel]  # type: ignore[arg-type]
                    idf1 = [float(r["idf1"]) for r in sel]  # type: ignore[arg-type]
                    points.append([v, float(np.mean(mota)), float(np.mean(idf1)), min(mota)])
            out.setdefault(axis, {})[tracker] = points
    return out


def merge_runs(
    old: list[dict[str, object]], new: list[dict[str, object]]
) -> list[dict[str, object]]:
    """``old`` runs of the trackers not in ``new``, then ``new``: one tracker's rows re-run.

    Only runs of the same seeds and duration are merged (``main`` checks the title).
    """
    rerun = {r["tracker"] for r in new}
    return [r for r in old if r["tracker"] not in rerun] + list(new)


def table(summary: dict[str, dict[str, list[list[float]]]]) -> str:
    """A Markdown table: one row per axis point, MOTA / IDF1 per tracker."""
    trackers = sorted({t for per in summary.values() for t in per})
    lines = [
        "| axis | value | " + " | ".join(f"{t} MOTA / IDF1" for t in trackers) + " |",
        "|---|---|" + "---|" * len(trackers),
    ]
    for axis, per in summary.items():
        for i, v in enumerate(AXES[axis].values):
            cells = []
            for t in trackers:
                pts = per.get(t, [])
                cells.append(f"{pts[i][1]:.3f} / {pts[i][2]:.3f}" if i < len(pts) else "-")
            lines.append(f"| {axis} | {v:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot(summary: dict[str, dict[str, list[list[float]]]], path: Path, title: str) -> None:
    """MOTA (top) and IDF1 (bottom) curves, one column per axis, one line per tracker."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(AXES), figsize=(4.2 * len(AXES), 7), sharey="row")
    for col, (axis, per) in enumerate(summary.items()):
        for tracker, pts in per.items():
            if not pts:
                continue
            arr = np.array(pts)
            for row, k in ((0, 1), (1, 2)):
                style, label = LOOKS.get(tracker, ("x-", tracker))
                axes[row, col].plot(arr[:, 0], arr[:, k], style, label=label)
        axes[1, col].set_xlabel(AXES[axis].label)
        for row in (0, 1):
            axes[row, col].grid(True, alpha=0.3)
            axes[row, col].axhline(0.6 if row == 0 else 0.85, color="grey", lw=0.8, ls=":")
    axes[0, 0].set_ylabel("MOTA")
    axes[1, 0].set_ylabel("IDF1")
    axes[0, 0].set_ylim(bottom=min(0.0, axes[0, 0].get_ylim()[0]), top=1.0)
    axes[1, 0].set_ylim(0.0, 1.0)
    axes[0, -1].legend(loc="lower left")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=list(SEEDS))
    parser.add_argument("--duration", type=float, default=DURATION_S)
    parser.add_argument("--trackers", nargs="+", default=list(TRACKERS), choices=TRACKERS)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--norfair-python", default=None, help="Python of norfair's venv")
    parser.add_argument("--make-norfair-env", action="store_true", help="create .venv-norfair")
    parser.add_argument("--quick", action="store_true", help="20 s, first seed, no files")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "robustness_sweep")
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE",
        help="a tracker setting for ours and identity (repeatable); pair it with --out elsewhere",
    )  # fmt: skip
    parser.add_argument(
        "--merge", action="store_true",
        help="keep the other trackers' runs already in --out's JSON; replace these trackers'",
    )  # fmt: skip
    args = parser.parse_args(argv)
    seeds, duration = (args.seeds[:1], 20.0) if args.quick else (args.seeds, args.duration)
    title = (
        f"{SCENARIO}, realistic profile made worse one axis at a time; "
        f"{duration:g} s, seeds {', '.join(map(str, seeds))}"
    )
    results = args.out.with_suffix(".json")
    old = None
    if args.merge and results.exists():
        old = json.loads(results.read_text())
        if old["title"] != title:
            print(
                f"sweep: --merge: {results} holds runs of {old['title']!r}, not "
                f"{title!r}: give its seeds and duration, or another --out",
                file=sys.stderr,
            )
            return 2
    norfair = args.norfair_python
    if norfair is None and (args.make_norfair_env or (NORFAIR_ENV / "bin" / "python").exists()):
        norfair = make_norfair_env()
    trackers = [t for t in args.trackers if t != "norfair" or norfair]
    if "norfair" in args.trackers and not norfair:
        print("sweep: norfair left out (no --norfair-python, no .venv-norfair)", file=sys.stderr)
    jobs = [
        (axis, v, t, s, min(duration, STONESOUP_BUDGET[1]) if t == "stonesoup" else duration,
         norfair, tuple(args.set))
        for axis, spec in AXES.items()
        for v in spec.values
        for t in trackers
        for s in (seeds[: STONESOUP_BUDGET[0]] if t == "stonesoup" else seeds)
    ]  # fmt: skip
    jobs.sort(key=lambda j: j[2] != "stonesoup")  # the slowest first, so the pool stays busy
    rows: list[dict[str, object]] = []
    start = time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as ex:
        for i, row in enumerate(ex.map(run_point, jobs), 1):
            rows.append(row)
            print(json.dumps(row), flush=True)
            elapsed = time.perf_counter() - start
            print(
                f"sweep: {i}/{len(jobs)} runs, {elapsed:.0f} s, "
                f"about {elapsed / i * (len(jobs) - i):.0f} s left",
                file=sys.stderr,
                flush=True,
            )
    if old is not None:
        rows = merge_runs(old["runs"], rows)
    summary = summarise(rows)
    print(table(summary))
    if not args.quick:
        results.write_text(
            json.dumps({"title": title, "summary": summary, "runs": rows}, indent=1) + "\n"
        )
        plot(summary, args.out.with_suffix(".png"), title)
        print(f"sweep: wrote {args.out.with_suffix('.png')}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
