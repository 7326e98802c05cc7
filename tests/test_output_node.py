"""End to end across real processes: simulated sensors -> tracker -> output -> UDP socket."""

from __future__ import annotations

import itertools
import signal
import socket
import statistics
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml

from openptrack_py.output.opt_json import parse_datagram
from tests.conftest import free_port

pytestmark = pytest.mark.zenoh

RATE_HZ = 20.0


def _udp_socket() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(0.5)
    return sock


def _network(tmp_path: Path, udp_port: int, **output: object) -> Path:
    net = {
        "site": "e2e",
        "zenoh": {"hub": f"tcp/127.0.0.1:{free_port()}"},
        # seven people walking 1-9 m from the first of three Kinect v2 (all in view); the
        # ideal sensors, so that the track count checks the output, not the tracker
        "sim": {
            "scenario": "crowd",
            "seed": 5,
            "use_scenario_sensors": True,
            "profile": "ideal",
        },
        "tracker": {},
        "outputs": [
            {
                "name": "out",
                "smoother": {"rate_hz": RATE_HZ},
                "udp": [{"host": "127.0.0.1", "port": udp_port, "heartbeat_interval_s": 0.25}],
                **output,
            }
        ],
    }
    path = tmp_path / "net.yaml"
    path.write_text(yaml.safe_dump(net))
    return path


def _receive(sock: socket.socket, seconds: float) -> list[tuple[float, bytes]]:
    got = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            data = sock.recv(65536)
        except TimeoutError:
            continue
        got.append((time.monotonic(), data))
    return got


def test_simulated_people_arrive_as_udp_frames_at_the_configured_rate(
    tmp_path: Path, spawn: Callable[..., subprocess.Popen[str]]
) -> None:
    sock = _udp_socket()
    net = _network(tmp_path, sock.getsockname()[1])
    launcher = spawn("-m", "openptrack_py.cli", "launch", str(net), "--status-interval", "0")
    try:
        # wait for the first frame with people in it, then let tracks settle
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if any(b'"people_tracks":[{' in d for _, d in _receive(sock, 0.5)):
                break
        else:
            pytest.fail(Path(launcher.log_path).read_text())  # type: ignore[attr-defined]
        _receive(sock, 2.0)
        got = _receive(sock, 6.0)
    finally:
        launcher.send_signal(signal.SIGINT)
        assert launcher.wait(timeout=30) == 0
        sock.close()

    frames = [(t, parse_datagram(d)) for t, d in got if b'"frame_id":"world"' in d]
    heartbeats = [parse_datagram(d) for _, d in got if b'"frame_id":"heartbeat"' in d]
    assert all(d.endswith(b"]}\x00") or d.endswith(b"}\x00") for _, d in got)
    # the configured rate: 20 frames per second, evenly spaced
    assert 0.85 * 6 * RATE_HZ <= len(frames) <= 1.1 * 6 * RATE_HZ
    gaps = [b[0] - a[0] for a, b in itertools.pairwise(frames)]
    assert statistics.median(gaps) == pytest.approx(1 / RATE_HZ, rel=0.2)
    seqs = [f["header"]["seq"] for _, f in frames]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # none lost, none reordered
    # the expected track count: the seven people, in nearly every frame
    counts = [len(f["people_tracks"]) for _, f in frames]
    assert sum(c == 7 for c in counts) >= 0.9 * len(counts), counts
    ids = {t["id"] for _, f in frames for t in f["people_tracks"]}
    assert len(ids) <= 8  # stable ids: at most one change over six seconds
    # heartbeats every 0.25 s with the tracker's alive ids
    assert 0.8 * 6 / 0.25 <= len(heartbeats) <= 1.2 * 6 / 0.25
    assert all(len(h["alive_IDs"]) >= 7 and h["max_ID"] >= 7 for h in heartbeats)


def test_raw_source_sends_every_tracker_step(
    tmp_path: Path, spawn: Callable[..., subprocess.Popen[str]]
) -> None:
    sock = _udp_socket()
    net = _network(tmp_path, sock.getsockname()[1], source="raw")
    launcher = spawn("-m", "openptrack_py.cli", "launch", str(net), "--status-interval", "0")
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if any(b'"people_tracks":[{' in d for _, d in _receive(sock, 0.5)):
                break
        got = _receive(sock, 3.0)
    finally:
        launcher.send_signal(signal.SIGINT)
        assert launcher.wait(timeout=30) == 0
        sock.close()
    frames = [d for _, d in got if b'"frame_id":"world"' in d]
    # three sensors at 30 Hz: about 90 tracker steps per second, each sent as it comes
    assert len(frames) >= 0.7 * 3 * 90
