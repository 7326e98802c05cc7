"""Is the simulator honest? Per-frame detection rates and errors of one sensor per type.

Runs the ``crowd``, ``distance`` and ``occlusions`` scenes (the OpenPTrack paper's three
test sequences, one sensor each: the scene's first sensor, turned into each type) under
the ``realistic`` and ``ideal`` noise profiles, and measures, per frame of the sensor:

* **recall**: the share of the people in the sensor's view (head inside its field of
  view and range, occlusion ignored: what a person annotating its images would count)
  who got a detection (by the observation's ground-truth person ids);
* **false positives** per frame, and as a share of the people in view; ``confident``
  ones have a confidence of at least 0.5, ``decoy`` ones lie within 0.5 m of a decoy;
* the **floor error** of the true detections (metres): mean and standard deviation,
  overall and for people 2-5 m from the sensor, and the mean by distance.

These are single-sensor, per-frame detection figures; the OpenPTrack paper's FN/FP are
after its tracker (so recall here should be of the order of 1 - FN, and false positives
of the order of FP). Prints one JSON line; ``--markdown`` prints the table of
``docs/evaluation.md`` instead. Run from the repository root::

    python -m benchmarks.profile_rates [--seeds 0 1 2] [--markdown]
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict

import numpy as np

from benchmarks.common import emit
from openptrack_py.config import SensorConfig
from openptrack_py.messages.detection import Detection
from openptrack_py.sim import Simulator, build_scenario

SCENES = ("crowd", "distance", "occlusions")
TYPES = ("kinect2", "kinect1", "sr4500", "realsense")
PROFILES = ("realistic", "ideal")
BINS = ((0.0, 2.0), (2.0, 5.0), (5.0, 8.0), (8.0, 12.0))
"""Distance bins (metres from the sensor, on the floor) of the error by distance."""


def measure(scene: str, sensor_type: str, profile: str, seed: int) -> dict[str, list[float]]:
    """Raw per-frame counts and per-detection errors of one run."""
    base = build_scenario(scene, seed=seed)
    sensor = SensorConfig(id="s", type=sensor_type, pose=base.sensors[0].pose)  # type: ignore[arg-type]
    scenario = build_scenario(scene, seed=seed, sensors=[sensor], profile=profile)
    sim = Simulator(scenario, ground_truth_rate_hz=None)
    model = sim.models[0]
    spec = model.spec
    decoys = np.array([(d.x, d.y) for d in scenario.decoys]).reshape(-1, 2)
    raw: dict[str, list[float]] = defaultdict(list)
    end = scenario.duration_s or 0.0
    k = 0
    while (t := spec.phase_s + k / spec.rate_hz) <= end:
        k += 1
        snap = sim.world.state_at(t)
        obs = model.observe(snap)
        in_view = set(snap.ids[model.covers(snap.pos, snap.height)].tolist())
        found = {pid for pid in obs.person_ids if pid}
        raw["in_view"].append(len(in_view))
        raw["found"].append(len(found & in_view))
        fake = [d for d, pid in zip(obs.detections, obs.person_ids, strict=True) if not pid]
        raw["fp"].append(len(fake))
        raw["fp_confident"].append(sum(d.confidence >= 0.5 for d in fake))
        raw["fp_decoy"].append(sum(_near_decoy(d, decoys) for d in fake))
        row = {int(pid): i for i, pid in enumerate(snap.ids.tolist())}
        for det, pid in zip(obs.detections, obs.person_ids, strict=True):
            if not pid:
                continue
            truth = snap.pos[row[pid]]
            raw["error"].append(float(np.hypot(det.x - truth[0], det.y - truth[1])))
            raw["distance"].append(float(np.hypot(*(truth - model.origin[:2]))))
    return raw


def _near_decoy(det: Detection, decoys: np.ndarray) -> bool:
    """Whether a false detection is a decoy's (within 0.5 m of one)."""
    return bool(len(decoys)) and bool(np.hypot(*(decoys - (det.x, det.y)).T).min() < 0.5)


def summarise(raw: dict[str, list[float]]) -> dict[str, object]:
    """The figures of pooled raw measurements."""
    in_view = float(np.sum(raw["in_view"]))
    frames = len(raw["in_view"])
    err = np.asarray(raw["error"])
    dist = np.asarray(raw["distance"])
    mid = err[(dist >= 2.0) & (dist <= 5.0)]
    by_distance = {}
    for lo, hi in BINS:
        e = err[(dist >= lo) & (dist < hi)]
        if len(e) >= 30:
            by_distance[f"{lo:g}-{hi:g}"] = round(float(e.mean()), 3)
    return {
        "frames": frames,
        "people_in_view_per_frame": round(in_view / max(frames, 1), 2),
        "recall": round(float(np.sum(raw["found"])) / max(in_view, 1.0), 3),
        "fp_per_frame": round(float(np.mean(raw["fp"])), 3),
        "fp_share": round(float(np.sum(raw["fp"])) / max(in_view, 1.0), 3),
        "confident_fp_per_frame": round(float(np.mean(raw["fp_confident"])), 3),
        "decoy_fp_per_frame": round(float(np.mean(raw["fp_decoy"])), 3),
        "error_mean_m": round(float(err.mean()), 3) if len(err) else None,
        "error_std_m": round(float(err.std()), 3) if len(err) else None,
        "error_p95_m": round(float(np.percentile(err, 95)), 3) if len(err) else None,
        "error_2_5m_mean_m": round(float(mid.mean()), 3) if len(mid) else None,
        "error_2_5m_std_m": round(float(mid.std()), 3) if len(mid) else None,
        "error_by_distance_m": by_distance,
    }


def run(seeds: list[int]) -> dict[str, dict[str, object]]:
    """Figures per ``profile/scene/type`` and pooled over the scenes per ``profile/type``."""
    out: dict[str, dict[str, object]] = {}
    for profile in PROFILES:
        for kind in TYPES:
            pooled: dict[str, list[float]] = defaultdict(list)
            for scene in SCENES:
                raw: dict[str, list[float]] = defaultdict(list)
                for seed in seeds:
                    for key, values in measure(scene, kind, profile, seed).items():
                        raw[key] += values
                        pooled[key] += values
                out[f"{profile}/{scene}/{kind}"] = summarise(raw)
                print(f"{profile}/{scene}/{kind} done", file=sys.stderr)
            out[f"{profile}/all/{kind}"] = summarise(pooled)
    return out


PAPER_FN_FP = {
    ("crowd", "kinect2"): (29.5, 9.3),
    ("crowd", "kinect1"): (54.2, 1.0),
    ("crowd", "sr4500"): (40.4, 8.7),
    ("distance", "kinect2"): (7.1, 3.2),
    ("distance", "kinect1"): (43.5, 1.6),
    ("distance", "sr4500"): (34.5, 1.2),
    ("occlusions", "kinect2"): (45.3, 6.2),
    ("occlusions", "kinect1"): (67.1, 0.4),
    ("occlusions", "sr4500"): (63.9, 4.1),
}
"""OpenPTrack paper, Tables 2-4: tracker FN and FP, percent of the ground-truth people."""


def markdown(figures: dict[str, dict[str, object]]) -> str:
    """The comparison table of ``docs/evaluation.md``."""
    head = (
        "| scene | sensor | paper FN / FP % | realistic: 1 - recall | FP / people in view "
        "| FP per frame: all / conf >= 0.5 / decoy | error 2-5 m mean / std (m) "
        "| ideal: 1 - recall | FP / people | error 2-5 m |\n"
        "|---|---|---|---|---|---|---|---|---|---|"
    )
    lines = [head]
    for scene in SCENES:
        for kind in TYPES:
            r = figures[f"realistic/{scene}/{kind}"]
            i = figures[f"ideal/{scene}/{kind}"]
            paper = PAPER_FN_FP.get((scene, kind))
            paper_text = f"{paper[0]:.1f} / {paper[1]:.1f}" if paper else "-"
            lines.append(
                f"| {scene} | {kind} | {paper_text} | {100 * (1 - r['recall']):.1f} % "
                f"| {100 * r['fp_share']:.1f} % | {r['fp_per_frame']:.2f} / "
                f"{r['confident_fp_per_frame']:.2f} / {r['decoy_fp_per_frame']:.2f} "
                f"| {r['error_2_5m_mean_m']} / {r['error_2_5m_std_m']} "
                f"| {100 * (1 - i['recall']):.1f} % | {100 * i['fp_share']:.1f} % "
                f"| {i['error_2_5m_mean_m']} / {i['error_2_5m_std_m']} |"
            )
    lines.append("")
    lines.append(
        "| all three scenes | mean error by distance (m), realistic | ideal |\n|---|---|---|"
    )
    for kind in TYPES:
        r = figures[f"realistic/all/{kind}"]["error_by_distance_m"]
        i = figures[f"ideal/all/{kind}"]["error_by_distance_m"]
        fmt = ", ".join(f"{k} m: {v}" for k, v in r.items())  # type: ignore[union-attr]
        fmt_i = ", ".join(f"{k} m: {v}" for k, v in i.items())  # type: ignore[union-attr]
        lines.append(f"| {kind} | {fmt} | {fmt_i} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> dict[str, object]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--markdown", action="store_true", help="print the docs table")
    args = parser.parse_args(argv)
    figures = run(args.seeds)
    if args.markdown:
        sys.stdout.write(markdown(figures))
        return {"benchmark": "profile_rates", **figures}
    return emit("profile_rates", {"seeds": args.seeds, **figures})


if __name__ == "__main__":
    main()
