"""End-to-end latency and output-rate jitter, across real processes on loopback.

Latency: this process publishes detection batches over Zenoh (30 Hz, one person walking,
``stamp`` = the wall-clock time of the put); a tracker node and an output node (``source:
raw``, one UDP JSON sink to this process) run as separate processes; each datagram's
header stamp is the stamp of the batch that produced it, so ``receive time - stamp`` is
the time from the detection put to the datagram out, through two Zenoh hops, the tracker
step and the UDP encoder. Target: p50 <= 2 ms, p99 <= 10 ms.

Jitter: the same chain with ``source: smoothed`` at 30 Hz; the spread of the gaps
between datagrams received here (the smoother's fixed-rate ticker plus the UDP send).

Prints one JSON line (milliseconds).

Run from the repository root::

    python -m benchmarks.bench_end_to_end
"""

from __future__ import annotations

import itertools
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import yaml

from benchmarks.common import emit, percentiles
from openptrack_py.config import ZenohConfig
from openptrack_py.messages import Detection, DetectionBatch, encode_detection_batch
from openptrack_py.output.opt_json import parse_datagram
from openptrack_py.runtime.ports import free_port
from openptrack_py.transport import wait_for_subscribers
from openptrack_py.transport.zenoh_bus import ZenohBus

ROOT = Path(__file__).resolve().parent.parent


def _start(net: Path, node: str, name: str | None = None) -> subprocess.Popen[bytes]:
    args = [sys.executable, "-m", f"openptrack_py.nodes.{node}", "-c", str(net)]
    args += ["--log-level", "warning", *(["--name", name] if name else [])]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(args, cwd=ROOT, env=env)


def run(source: str, frames: int, rate_hz: float = 30.0) -> list[tuple[float, dict]]:
    """Drive the chain with ``frames`` batches; return (receive time, datagram) pairs."""
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    udp.bind(("127.0.0.1", 0))
    udp.settimeout(0.2)
    hub = f"tcp/127.0.0.1:{free_port()}"
    net = {
        "site": "bench",
        "zenoh": {"hub": hub},
        "tracker": {},
        "outputs": [
            {
                "name": "out",
                "source": source,
                "republish": False,
                "smoother": {"rate_hz": rate_hz},
                "udp": [{"host": "127.0.0.1", "port": udp.getsockname()[1], "heartbeat": False}],
            }
        ],
    }
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "net.yaml"
        path.write_text(yaml.safe_dump(net))
        bus = ZenohBus(ZenohConfig(hub=hub), as_hub=True)
        procs = [_start(path, "tracker"), _start(path, "output", "out")]
        received: list[tuple[float, dict]] = []
        stop = threading.Event()

        def receive() -> None:  # timestamps each datagram the moment it lands
            while not stop.is_set():
                try:
                    data = udp.recv(65536)
                except TimeoutError:
                    continue
                received.append((time.time(), parse_datagram(data)))

        reader = threading.Thread(target=receive, daemon=True)
        reader.start()
        try:
            pub = bus.publisher("opt/bench/detections/k1")
            if not wait_for_subscribers(pub, 30):
                raise RuntimeError("the tracker did not subscribe")
            time.sleep(1.0)  # let the output node subscribe to the tracks too
            period = 1.0 / rate_hz
            start = time.monotonic()
            for k in range(frames):
                x = 1.0 + 0.04 * k % 6.0
                det = Detection(x=x, y=2.0, z=0.9, height=1.75, confidence=0.9, distance=3.0)
                batch = DetectionBatch("k1", k, time.time(), "world", (det,))
                pub.put(encode_detection_batch(batch))
                time.sleep(max(0.0, start + (k + 1) * period - time.monotonic()))
            time.sleep(0.5)
        finally:
            stop.set()
            reader.join()
            for p in procs:
                p.terminate()
            for p in procs:
                p.wait(10)
            bus.close()
            udp.close()
    return received


def main(frames: int = 900) -> dict[str, object]:
    raw = run("raw", frames)
    latencies = [
        t - (d["header"]["stamp"]["sec"] + d["header"]["stamp"]["nsec"] * 1e-9)
        for t, d in raw
        if d["header"]["frame_id"] == "world" and d["people_tracks"]
    ][60:]  # after the track is confirmed and everything is warm
    smoothed = run("smoothed", frames)
    arrivals = [t for t, d in smoothed if d["header"]["frame_id"] == "world"][30:]
    gaps = [b - a for a, b in itertools.pairwise(arrivals)]
    deviation = [abs(g - 1 / 30.0) for g in gaps]
    return emit(
        "end_to_end_ms",
        {
            "detection_put_to_udp_out": percentiles(latencies, 1e3),
            "targets_met": {
                "p50_le_2ms": statistics.median(latencies) * 1e3 <= 2.0,
                "p99_le_10ms": percentiles(latencies, 1e3)["p99"] <= 10.0,
            },
            "smoothed_30hz_period": {
                "mean": round(statistics.mean(gaps) * 1e3, 3),
                "stdev": round(statistics.pstdev(gaps) * 1e3, 3),
                "abs_deviation": percentiles(deviation, 1e3),
            },
        },
    )


if __name__ == "__main__":
    main()
