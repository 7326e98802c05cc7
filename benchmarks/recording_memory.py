"""Hour-long recordings: replay and analysis stream, so memory stays flat.

Writes an hour of the ``stress`` scenario (120 people in a hall) as a recording: the
ground truth once a second and the people as tracks ten times a second (what an output
node's smoothed stream gives; a tracker's raw stream is ten times denser), then runs
``openptrack analyze`` and ``openptrack replay --speed 200`` on it as processes and
samples their resident memory twice a second. Memory is flat when the last tenth of
the run is within 10 % of the first tenth after start-up. Prints JSON::

    python -m benchmarks.recording_memory              # one hour
    python -m benchmarks.recording_memory --minutes 5  # quicker
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from openptrack_py.messages import Track, TrackBatch
from openptrack_py.messages.codec import encode_ground_truth, encode_track_batch
from openptrack_py.messages.ground_truth import GroundTruthFrame, PersonState
from openptrack_py.recordings import open_writer
from openptrack_py.sim.scenarios import build_scenario, scenario_world

ROOT = Path(__file__).resolve().parent.parent
START = 1_764_000_000.0


def write_recording(path: Path, minutes: float, tracks_hz: float = 10.0) -> int:
    """An hour (or ``minutes``) of ``stress`` as tracks and ground truth; messages written."""
    scenario = build_scenario("stress", seed=3, duration_s=minutes * 60)
    world = scenario_world(scenario, dt=1.0 / tracks_hz)
    writer = open_writer(
        path, {"openptrack": {"site": "default", "benchmark": "recording_memory"}}
    )
    count, step = 0, 0
    t = 0.0
    while t < minutes * 60:
        snap = world.state_at(t)
        stamp = START + t
        tracks = tuple(
            Track(id=int(pid), x=float(x), y=float(y), z=0.9, height=1.7, vx=float(vx),
                  vy=float(vy), age=t, confidence=0.9, visibility=1)
            for pid, (x, y), (vx, vy) in zip(snap.ids, snap.pos, snap.vel, strict=True)
        )  # fmt: skip
        ids = tuple(tr.id for tr in tracks)
        batch = TrackBatch(stamp, step, "world", tracks, ids, max(ids, default=0))
        writer.write(stamp + 0.01, "opt/default/tracks", encode_track_batch(batch))
        count += 1
        if step % int(tracks_hz) == 0:
            people = tuple(
                PersonState(int(pid), float(x), float(y), 1.7, float(vx), float(vy), "adult", True)
                for pid, (x, y), (vx, vy) in zip(snap.ids, snap.pos, snap.vel, strict=True)
            )
            writer.write(stamp, "opt/default/ground_truth",
                         encode_ground_truth(GroundTruthFrame(stamp, step, people)))  # fmt: skip
            count += 1
        step += 1
        t = step / tracks_hz
        if step % int(600 * tracks_hz) == 0:
            print(
                f"recording_memory: wrote {t / 60:.0f} of {minutes:.0f} minutes", file=sys.stderr
            )
    writer.close()
    return count


def sampled_rss(cmd: list[str]) -> dict[str, object]:
    """Run ``cmd``; its resident memory twice a second, wall time and exit status."""
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT)
    samples = []
    start = time.monotonic()
    while proc.poll() is None:
        try:
            text = Path(f"/proc/{proc.pid}/status").read_text()
            rss = int(next(x for x in text.splitlines() if x.startswith("VmRSS:")).split()[1])
            samples.append((round(time.monotonic() - start, 1), round(rss / 1024, 1)))
        except (OSError, StopIteration):
            pass
        time.sleep(0.5)
    rss = np.array([s[1] for s in samples]) if samples else np.zeros(1)
    tenth = max(len(rss) // 10, 1)
    settled, last = rss[tenth : 2 * tenth].mean(), rss[-tenth:].mean()
    return {
        "exit": proc.returncode,
        "wall_s": round(time.monotonic() - start, 1),
        "rss_mib_max": float(rss.max()),
        "rss_mib_second_tenth": round(float(settled), 1),
        "rss_mib_last_tenth": round(float(last), 1),
        "flat_within_10_percent": bool(abs(last / settled - 1) <= 0.10),
        "samples": samples,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=60.0)
    parser.add_argument("--out", type=Path, help="also write the JSON here")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "stress.mcap"
        start = time.monotonic()
        messages = write_recording(path, args.minutes)
        written_s = time.monotonic() - start
        cli = [sys.executable, "-m", "openptrack_py.cli"]
        analyze = sampled_rss([*cli, "analyze", str(path), "--format", "json"])
        replay = sampled_rss([*cli, "replay", str(path), "--topics", "tracks", "--speed", "200",
                              "-e", "tcp/127.0.0.1:9", "--no-multicast-scouting"])  # fmt: skip
        figures = {
            "benchmark": "recording_memory",
            "recording": {
                "minutes": args.minutes,
                "people": 120,
                "messages": messages,
                "mib": round(path.stat().st_size / 2**20, 1),
                "write_s": round(written_s, 1),
            },
            "analyze": analyze,
            "replay_x200": replay,
        }
    if args.out is not None:
        args.out.write_text(json.dumps(figures, indent=1) + "\n")
    summary = {
        k: ({kk: vv for kk, vv in v.items() if kk != "samples"} if isinstance(v, dict) else v)
        for k, v in figures.items()
    }
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
