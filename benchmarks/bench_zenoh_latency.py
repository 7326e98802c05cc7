"""Zenoh put->receive latency between two processes on loopback, with a UDP baseline.

A child process publishes encoded 20-detection batches at 200 Hz through ``ZenohBus``
(peer mode, explicit endpoint, multicast off, BLOCK congestion control); this process
receives them and records ``receive - put`` on the shared monotonic clock. The same
is measured for a raw UDP socket between the same two processes, in the same run, as the
floor Python can reach. Prints one JSON line (milliseconds).

Run from the repository root::

    python -m benchmarks.bench_zenoh_latency [--count N] [--rate HZ]
"""

from __future__ import annotations

import argparse
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

from benchmarks.bench_codec import batch
from benchmarks.common import emit, percentiles
from openptrack_py.config import ZenohConfig
from openptrack_py.messages import encode_detection_batch
from openptrack_py.runtime.ports import free_port
from openptrack_py.transport import wait_for_subscribers
from openptrack_py.transport.zenoh_bus import ZenohBus

KEY = "opt/bench/detections/k1"
ROOT = Path(__file__).resolve().parent.parent
_STAMP = struct.Struct("<Qi")  # monotonic ns of the put, sequence number


def child(mode: str, target: str, count: int, rate_hz: float) -> int:
    """Sender side (runs in the child process)."""
    payload = encode_detection_batch(batch(20))
    period = 1.0 / rate_hz
    if mode == "zenoh":
        cfg = ZenohConfig(hub=None, connect=[target], listen=[], multicast_scouting=False)
        with ZenohBus(cfg) as bus:
            pub = bus.publisher(KEY, reliable=True)
            if not wait_for_subscribers(pub, timeout_s=20):
                return 3
            time.sleep(0.2)
            for i in range(count):
                pub.put(_STAMP.pack(time.monotonic_ns(), i) + payload)
                time.sleep(period)
        return 0
    host, port = target.rsplit(":", 1)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        for i in range(count):
            s.sendto(_STAMP.pack(time.monotonic_ns(), i) + payload, (host, int(port)))
            time.sleep(period)
    return 0


def _spawn(mode: str, target: str, count: int, rate_hz: float) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-m", "benchmarks.bench_zenoh_latency", "--child", mode, target,
         "--count", str(count), "--rate", str(rate_hz)],
        cwd=ROOT,
    )  # fmt: skip


def measure_zenoh(count: int, rate_hz: float) -> tuple[list[float], int]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    cfg = ZenohConfig(hub=None, listen=[endpoint], connect=[], multicast_scouting=False)
    latencies: list[float] = []
    done = threading.Event()
    seen: list[int] = []
    with ZenohBus(cfg) as bus:

        def on_sample(sample: object) -> None:
            now = time.monotonic_ns()
            sent, seq = _STAMP.unpack_from(sample.payload)  # type: ignore[attr-defined]
            latencies.append((now - sent) / 1e6)
            seen.append(seq)
            if seq == count - 1:
                done.set()

        sub = bus.subscribe(KEY, on_sample)
        proc = _spawn("zenoh", endpoint, count, rate_hz)
        done.wait(timeout=count / rate_hz + 30)
        proc.wait(timeout=30)
        sub.close()
    return latencies, len(set(seen))


def measure_udp(count: int, rate_hz: float) -> tuple[list[float], int]:
    latencies: list[float] = []
    received = 0
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        s.settimeout(5.0)
        target = f"127.0.0.1:{s.getsockname()[1]}"
        proc = _spawn("udp", target, count, rate_hz)
        try:
            while received < count:
                data = s.recv(65536)
                now = time.monotonic_ns()
                sent, _ = _STAMP.unpack_from(data)
                latencies.append((now - sent) / 1e6)
                received += 1
        except TimeoutError:
            pass
        proc.wait(timeout=30)
    return latencies, received


def main(count: int = 2000, rate_hz: float = 200.0) -> dict[str, object]:
    zenoh_lat, zenoh_n = measure_zenoh(count, rate_hz)
    udp_lat, udp_n = measure_udp(count, rate_hz)
    warm = 50  # first samples include connection set-up
    z = percentiles(zenoh_lat[warm:])
    u = percentiles(udp_lat[warm:])
    return emit(
        "zenoh_put_to_receive_ms",
        {
            "payload_bytes": len(encode_detection_batch(batch(20))) + _STAMP.size,
            "rate_hz": rate_hz,
            "zenoh": {**z, "received": zenoh_n, "sent": count},
            "udp_baseline": {**u, "received": udp_n, "sent": count},
            "p50_ratio_zenoh_over_udp": round(z["p50"] / u["p50"], 2) if u["p50"] else None,
        },
    )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--child", nargs=2, metavar=("MODE", "TARGET"), help=argparse.SUPPRESS)
    parser.add_argument("--count", type=int, default=2000)
    parser.add_argument("--rate", type=float, default=200.0)
    args = parser.parse_args()
    if args.child:
        sys.exit(child(args.child[0], args.child[1], args.count, args.rate))
    main(args.count, args.rate)
