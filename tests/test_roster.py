"""``openptrack roster`` against a running demo: real processes, real Zenoh, a real file.

The demo network runs (simulator, tracker with identity on, output); the roster commands
run as separate processes, register a person seen by the tracker, list and remove them,
and the tracker names that person's track in its published tracks.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import orjson
import pytest

from openptrack_py.tracking.identity import load_roster
from tests.conftest import ROOT, demo_network_file, free_port, python_env, wait_for


def _cli(net: Path, *args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "openptrack_py.cli", *args, "-c", str(net)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=python_env(),
        cwd=ROOT,
    )


def _tracks(net: Path, n: int) -> list[dict]:
    echo = _cli(net, "echo", "opt/default/tracks", "-n", str(n))
    assert echo.returncode == 0, echo.stderr
    return [orjson.loads(x)["msg"] for x in echo.stdout.splitlines()]


def _oldest_track(net: Path) -> int | None:
    msgs = _tracks(net, 3)
    tracks = [t for m in msgs for t in m.get("tracks", [])]
    if not tracks:
        return None
    return max(tracks, key=lambda t: t["age"])["id"] if max(t["age"] for t in tracks) > 3 else None


@pytest.mark.zenoh
@pytest.mark.slow
def test_roster_commands_against_a_running_demo(
    tmp_path: Path, spawn: Callable[..., subprocess.Popen[str]]
) -> None:
    roster_file = tmp_path / "roster.yaml"
    identity = {"identity": {"enabled": True, "roster_file": str(roster_file)}}
    net = demo_network_file(tmp_path, f"tcp/127.0.0.1:{free_port()}", tracker=identity)
    launcher = spawn("-m", "openptrack_py.cli", "launch", str(net), "--status-interval", "0")
    log = Path(launcher.log_path)  # type: ignore[attr-defined]
    wait_for(lambda: "playing scenario" in log.read_text(), 30, "the sim node to start")

    # a person seen long enough to have a colour model
    found: list[int] = []
    wait_for(lambda: bool(found.append(_oldest_track(net)) or found[-1]), 60, "a track 3 s old")
    track = found[-1]

    added = _cli(net, "roster", "add", "Ada", "--track", str(track))
    assert added.returncode == 0, added.stdout + added.stderr
    assert "roster: add Ada: done (1 registered)" in added.stdout
    assert load_roster(roster_file).names == ("Ada",)

    listed = _cli(net, "roster", "list", "--format", "json")
    assert listed.returncode == 0, listed.stderr
    assert [p["name"] for p in orjson.loads(listed.stdout)] == ["Ada"]

    # the tracker names someone from the roster, never on two tracks at once (whether it
    # is the right person is measured by benchmarks/identity.py: colour alone confuses
    # people who dress alike)
    deadline = time.monotonic() + 30
    named: list[dict] = []
    while time.monotonic() < deadline and not named:
        for msg in _tracks(net, 10):
            names = [t.get("identity") for t in msg.get("tracks", []) if t.get("identity")]
            assert len(names) == len(set(names))
            named += [t for t in msg.get("tracks", []) if t.get("identity") == "Ada"]
    assert named, "the registered person was never named"

    missing = _cli(net, "roster", "add", "Bo", "--track", "999999")
    assert missing.returncode == 2
    assert "no track 999999" in missing.stderr

    removed = _cli(net, "roster", "remove", "Ada")
    assert removed.returncode == 0, removed.stderr
    assert load_roster(roster_file).names == ()
    unknown = _cli(net, "roster", "remove", "Ada")
    assert unknown.returncode == 2 and "nobody named 'Ada'" in unknown.stderr
    launcher.terminate()
    try:
        code = launcher.wait(timeout=20)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the launcher did not stop 20 s after SIGTERM:\n{log.read_text()[-4000:]}")
    assert code == 0
