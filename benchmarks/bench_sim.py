"""Simulator speed: simulated seconds per wall second and sensor frames per second.

Runs ``stress`` (120 people, 10 sensors at 30 Hz) and ``crowd`` (7 people, 3 sensors)
offline, without sleeping, and prints one JSON line.

Run from the repository root::

    python -m benchmarks.bench_sim
"""

from __future__ import annotations

import time

from benchmarks.common import emit
from openptrack_py.sim import SensorFrame, Simulator, build_scenario


def run(name: str, duration_s: float, seed: int = 0) -> dict[str, float]:
    sim = Simulator(build_scenario(name, seed=seed, duration_s=duration_s))
    frames = detections = 0
    start = time.perf_counter()
    for event in sim.events():
        if isinstance(event, SensorFrame):
            frames += 1
            detections += len(event.batch.detections)
    wall = time.perf_counter() - start
    return {
        "sim_seconds": duration_s,
        "wall_seconds": round(wall, 3),
        "faster_than_real_time": round(duration_s / wall, 2),
        "sensor_frames_per_s": round(frames / wall, 1),
        "people": len(sim.world.slots),
        "sensors": len(sim.models),
        "detections_per_frame": round(detections / max(frames, 1), 2),
    }


def main() -> dict[str, object]:
    return emit("simulator_speed", {"stress": run("stress", 20.0), "crowd": run("crowd", 30.0)})


if __name__ == "__main__":
    main()
