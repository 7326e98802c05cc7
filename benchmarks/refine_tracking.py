"""Tracking with refined poses against tracking with the true ones (``crowd``, realistic).

Per seed: the crowd's three sensors believe poses 10-20 cm and 2-4 degrees off; one
person walks 60 s through the room; the walk refines the poses
(:func:`openptrack_py.calibration.walk.refine_walk`); then 60 s of ``crowd`` are tracked
three times, through the perturbed, the refined and the true poses. Prints one JSON line
per seed (disagreement between sensors before and after, MOTA and IDF1 of each run).

Run from the repository root (about 2 minutes per seed on 2 cores)::

    python -m benchmarks.refine_tracking --seed 41 --seed 42 --seed 43
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from openptrack_py.calibration.files import SensorCalibration
from openptrack_py.calibration.walk import refine_walk
from openptrack_py.config import PoseError, SensorConfig
from openptrack_py.eval.trackers import run_eval
from openptrack_py.eval.walk import simulate_walk
from openptrack_py.sim.scenarios import build_scenario


def perturbed_sensors(seed: int) -> list[SensorConfig]:
    """The crowd's sensors, each believing a pose 10-20 cm and 2-4 degrees off."""
    rng = np.random.default_rng(1000 + seed)
    out = []
    for spec in build_scenario("crowd", seed=seed).sensors:
        r, a = rng.uniform(0.10, 0.20), rng.uniform(0, 2 * np.pi)
        yaw = float(rng.choice([-1, 1]) * rng.uniform(2, 4))
        error = PoseError(dx=r * np.cos(a), dy=r * np.sin(a), dyaw_deg=yaw)
        out.append(SensorConfig(id=spec.id, type=spec.type.name, pose=spec.pose, pose_error=error))
    return out


def measure(seed: int, duration_s: float = 60.0) -> dict[str, object]:
    """One seed's refinement and the three tracking runs."""
    sensors = perturbed_sensors(seed)
    walk = simulate_walk("crowd", seed=seed + 500, duration_s=60.0, sensors=sensors)
    result = refine_walk(walk.tracks, walk.believed_poses, frame="floor")
    calibrations = {
        "perturbed": None,
        "refined": {
            s.id: SensorCalibration(pose=result.poses[s.id].to_pose(s.pose)) for s in sensors
        },
        "true": {s.id: SensorCalibration(pose=s.pose) for s in sensors},
    }
    runs = {}
    for name, calibration in calibrations.items():
        scenario = build_scenario(
            "crowd", seed=seed, duration_s=duration_s, sensors=sensors, profile="realistic",
            calibration=calibration,
        )  # fmt: skip
        m = run_eval(scenario, seed).metrics
        runs[name] = {"mota": round(m.mota, 4), "idf1": round(m.idf1, 4)}
    return {
        "seed": seed,
        "accepted": result.accepted,
        "disagreement_before_m": round(result.before.binned_m, 3),
        "disagreement_after_m": round(result.after.binned_m, 3),
        **runs,
        "mota_refined_minus_true": round(runs["refined"]["mota"] - runs["true"]["mota"], 4),
    }


def main() -> None:
    """Print one JSON line per ``--seed``."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, action="append", default=[])
    args = parser.parse_args()
    for seed in args.seed or [41, 42, 43]:
        print(json.dumps(measure(seed)), flush=True)


if __name__ == "__main__":
    main()
