"""Soak: the ``stress`` network (120 people, 10 sensors) live on this machine for minutes.

``openptrack launch`` runs the simulator, the tracker and an output node on loopback, as a
deployment would; this script reads the tracks from its own Zenoh session and samples,
every second, the tracker process's resident memory and CPU, the latency of every track
batch (arrival here minus the capture time of the batch it applied), and the tracker's
counters (``shed`` batches, ``steps``). The first minute is the warm-up; the figures are
over the rest. Writes JSON (``docs/soak.json``) and a plot (``docs/soak.png``)::

    python -m benchmarks.soak                   # 10 minutes
    python -m benchmarks.soak --minutes 2 --out /tmp/soak

Targets: p99 latency at most 250 ms; memory flat after the first minute: every sample
within 10 % of the mean, with the trend (least-squares slope) reported beside it.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from openptrack_py.config import ZenohConfig
from openptrack_py.messages.codec import (
    decode_detection_batch,
    decode_node_stats,
    decode_track_batch,
)
from openptrack_py.runtime.ports import free_port
from openptrack_py.transport.zenoh_bus import ZenohBus

ROOT = Path(__file__).resolve().parent.parent
WARMUP_S = 60.0


def network_file(directory: Path, hub_port: int) -> Path:
    """The stress network on loopback: simulator, tracker (with checkpoints), one output."""
    path = directory / "soak.yaml"
    path.write_text(
        f"""site: soak
zenoh: {{hub: "tcp/127.0.0.1:{hub_port}"}}
stats_interval_s: 1.0
sim: {{scenario: stress, use_scenario_sensors: true, profile: realistic}}
tracker: {{state_dir: "{directory / "state"}"}}
outputs:
  - name: output
    udp: [{{host: 127.0.0.1, port: {free_port()}}}]
"""
    )
    return path


def _tracker_pid(marker: str) -> int | None:
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmd = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if b"openptrack_py.nodes.tracker" in cmd and marker.encode() in b" ".join(cmd):
            return int(entry.name)
    return None


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _rss_mib(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def run(minutes: float, out: Path) -> dict[str, object]:
    with tempfile.TemporaryDirectory() as tmp:
        hub = free_port()
        net = network_file(Path(tmp), hub)
        launcher = subprocess.Popen(
            [sys.executable, "-m", "openptrack_py.cli", "launch", str(net),
             "--duration", str(minutes * 60 + 30)],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT,
        )  # fmt: skip
        cfg = ZenohConfig(hub=None, connect=[f"tcp/127.0.0.1:{hub}"], listen=[])
        lock = threading.Lock()
        latencies: list[tuple[float, float]] = []
        arrivals: list[tuple[float, float]] = []
        counters: dict[str, int] = {}
        timings: list[dict[str, float]] = []

        def on_tracks(sample: object) -> None:
            now = time.time()
            batch = decode_track_batch(sample.payload)  # type: ignore[attr-defined]
            with lock:
                latencies.append((now, now - batch.stamp))

        def on_detections(sample: object) -> None:
            now = time.time()
            batch = decode_detection_batch(sample.payload)  # type: ignore[attr-defined]
            with lock:
                arrivals.append((now, now - batch.stamp))

        def on_stats(sample: object) -> None:
            stats = decode_node_stats(sample.payload)  # type: ignore[attr-defined]
            with lock:
                counters.update(stats.counters)
                timings.append(stats.timings_ms)

        try:
            bus = _connect(cfg)
            bus.subscribe("opt/soak/tracks", on_tracks)
            bus.subscribe("opt/soak/stats/tracker", on_stats)
            bus.subscribe("opt/soak/detections/*", on_detections)
            pid = None
            deadline = time.time() + 60
            while pid is None and time.time() < deadline:
                pid = _tracker_pid(str(net))
                time.sleep(0.5)
            if pid is None:
                raise SystemExit("soak: the tracker did not start")
            samples = []
            start = time.time()
            last_cpu, last_t = _cpu_s(pid), start
            while time.time() - start < minutes * 60:
                time.sleep(1.0)
                now = time.time()
                cpu = _cpu_s(pid)
                with lock:
                    shed, steps = counters.get("shed", 0), counters.get("steps", 0)
                samples.append(
                    {
                        "t": round(now - start, 1),
                        "rss_mib": round(_rss_mib(pid), 1),
                        "cpu": round((cpu - last_cpu) / (now - last_t), 3),
                        "shed": shed,
                        "steps": steps,
                    }
                )
                last_cpu, last_t = cpu, now
                if int(now - start) % 30 == 0:
                    print(f"soak: {now - start:.0f} s of {minutes * 60:.0f}", file=sys.stderr)
            bus.close()
        finally:
            launcher.send_signal(signal.SIGINT)
            try:
                launcher.wait(timeout=30)
            except subprocess.TimeoutExpired:
                launcher.kill()
    return summarise(samples, latencies, arrivals, timings, start, minutes, out)


def _connect(cfg: ZenohConfig) -> ZenohBus:
    deadline = time.time() + 30
    while True:
        try:
            return ZenohBus(cfg)
        except Exception:
            if time.time() > deadline:
                raise
            time.sleep(0.5)


def _percentiles(delays: list[tuple[float, float]], start: float) -> dict[str, float]:
    lat = np.array([d for t, d in delays if t - start >= WARMUP_S]) * 1e3
    return {
        "p50": round(float(np.percentile(lat, 50)), 1),
        "p99": round(float(np.percentile(lat, 99)), 1),
        "max": round(float(lat.max()), 1),
        "batches": len(lat),
    }


def summarise(
    samples: list[dict], latencies: list[tuple[float, float]],
    arrivals: list[tuple[float, float]], timings: list[dict[str, float]], start: float,
    minutes: float, out: Path,
) -> dict[str, object]:  # fmt: skip
    """Figures after the warm-up, the JSON and the plot."""
    steady = [s for s in samples if s["t"] >= WARMUP_S]
    lat = np.array([d for t, d in latencies if t - start >= WARMUP_S]) * 1e3
    stages = sorted({k for t in timings[int(WARMUP_S) :] for k in t})
    rss = np.array([s["rss_mib"] for s in steady])
    minutes_in = np.array([s["t"] for s in steady]) / 60.0
    first, last = steady[0], steady[-1]
    span = max(last["t"] - first["t"], 1e-9)
    figures = {
        "benchmark": "soak",
        "network": "stress (120 people, 10 sensors), realistic profile, on loopback",
        "minutes": minutes,
        "warmup_s": WARMUP_S,
        "latency_ms": _percentiles(latencies, start),
        "detections_latency_ms": _percentiles(arrivals, start),
        "tracker_stage_ms": {
            k: round(float(np.mean([t[k] for t in timings[int(WARMUP_S) :] if k in t])), 3)
            for k in stages
        },
        "rss_mib": {
            "after_warmup": float(rss[0]),
            "mean": round(float(rss.mean()), 1),
            "min": float(rss.min()),
            "max": float(rss.max()),
            "end": float(rss[-1]),
            "largest_deviation_from_mean": round(float(np.abs(rss / rss.mean() - 1).max()), 3),
            "trend_mib_per_min": round(float(np.polyfit(minutes_in, rss, 1)[0]), 2),
        },
        "tracker_cpu": round(float(np.mean([s["cpu"] for s in steady])), 3),
        "steps_per_s": round((last["steps"] - first["steps"]) / span, 1),
        "shed_per_s": round((last["shed"] - first["shed"]) / span, 1),
        "targets": {
            "p99_latency_le_250_ms": bool(np.percentile(lat, 99) <= 250),
            "rss_flat_within_10_percent": bool(np.abs(rss / rss.mean() - 1).max() <= 0.10),
        },
        "samples": samples,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(figures, indent=1) + "\n")
    _plot(samples, latencies, start, out.with_suffix(".png"))
    print(json.dumps({k: v for k, v in figures.items() if k != "samples"}))
    return figures


def _plot(
    samples: list[dict], latencies: list[tuple[float, float]], start: float, path: Path
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.array([s["t"] for s in samples])
    fig, ax = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    ax[0].plot(t, [s["rss_mib"] for s in samples])
    ax[0].set_ylabel("tracker RSS (MiB)")
    ax[1].plot(t, [100 * s["cpu"] for s in samples])
    ax[1].set_ylabel("tracker CPU (%)")
    lt = np.array([a - start for a, _ in latencies])
    ld = np.array([d for _, d in latencies]) * 1e3
    edges = np.arange(0, t.max() + 10, 10)
    for q, style in ((50, "-"), (99, "--")):
        qs = [np.percentile(ld[(lt >= a) & (lt < a + 10)], q) if ((lt >= a) & (lt < a + 10)).any()
              else np.nan for a in edges[:-1]]  # fmt: skip
        ax[2].plot(edges[:-1] + 5, qs, style, label=f"p{q}")
    ax[2].axhline(250, color="grey", lw=0.8, ls=":")
    ax[2].set_ylabel("latency (ms), per 10 s")
    ax[2].set_xlabel("seconds")
    ax[2].legend()
    for a in ax:
        a.axvline(WARMUP_S, color="grey", lw=0.8, ls=":")
        a.grid(True, alpha=0.3)
    fig.suptitle("stress network live on this machine: tracker memory, CPU and latency")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "soak")
    args = parser.parse_args(argv)
    run(args.minutes, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
