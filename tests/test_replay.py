"""Record a running demo, re-track the recording, and replay it into a second demo."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml

from openptrack_py.recordings import read_recording
from tests.conftest import ROOT, demo_network_file, free_port, python_env, stop_process, wait_for

pytestmark = [pytest.mark.zenoh, pytest.mark.slow]


def _cli(*args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "openptrack_py.cli", *args],
        capture_output=True, text=True, env=python_env(), cwd=ROOT, timeout=timeout,
    )  # fmt: skip


class Udp:
    """Every datagram sent to a free UDP port on 127.0.0.1."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.frames: list[dict] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.sock.recv(65536)
            except OSError:
                continue
            self.frames.append(json.loads(data.rstrip(b"\0")))

    def people(self) -> list[list]:
        return [f["people_tracks"] for f in self.frames if f.get("people_tracks")]

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
        self.sock.close()


def test_a_demo_recording_retracks_exactly_and_replays_into_another_demo(
    tmp_path: Path,
) -> None:
    # 1. the demo, recorded from before its first frame (the simulation starts in 4 s)
    run = tmp_path / "run.mcap"
    first = tmp_path / "first"
    first.mkdir()
    net = demo_network_file(
        first, f"tcp/127.0.0.1:{free_port()}", sim={"start_time": time.time() + 4.0}
    )
    data = yaml.safe_load(net.read_text())
    data["recorder"] = {"path": str(run)}
    net.write_text(yaml.safe_dump(data))
    done = _cli("launch", str(net), "--duration", "11", "--status-interval", "0")
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    recording = read_recording(run)
    topics = {m.topic.split("/")[0] for m in recording}
    assert recording.stopped is None and {"detections", "tracks", "ground_truth"} <= topics

    # 2. retrack with the recorded settings: every step as the tracker took it
    retracked = _cli("retrack", str(run), "--format", "json")
    assert retracked.returncode == 0, retracked.stderr
    row = json.loads(retracked.stdout)
    assert row["mode"] == "as run" and row["first_step"] == 1 and row["missing"] == 0
    assert row["steps"] > 100 and row["identical"] == row["steps"], row

    # 3. a second demo with no simulator, fed by the replay; its UDP client reads as usual
    udp = Udp()
    second = tmp_path / "second"
    second.mkdir()
    hub = f"tcp/127.0.0.1:{free_port()}"
    net2 = demo_network_file(second, hub)
    data = yaml.safe_load(net2.read_text())
    data.pop("sim")
    for sensor in data["sensors"]:  # the recorded sensors, on machines not started here
        sensor.update(source="camera", host="sensor-pc", input="realsense")
    data["outputs"][0]["udp"] = [{"host": "127.0.0.1", "port": udp.port}]
    net2.write_text(yaml.safe_dump(data))
    launcher = subprocess.Popen(
        [sys.executable, "-m", "openptrack_py.cli", "launch", str(net2), "--status-interval",
         "0"], stdout=(second / "launch.log").open("w"), stderr=subprocess.STDOUT,
        env=python_env(), cwd=ROOT,
    )  # fmt: skip
    try:
        wait_for(lambda: len(udp.frames) > 10, 30, "the second demo's UDP heartbeat")
        assert not udp.people()  # nobody before the replay
        replayed = _cli("replay", str(run), "-c", str(net2))
        assert replayed.returncode == 0, replayed.stderr
        assert "replayed" in replayed.stdout
    finally:
        stop_process(launcher)
        udp.close()
    assert len(udp.people()) > 60, (second / "launch.log").read_text()[-2000:]
