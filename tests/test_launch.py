"""The launcher: which nodes run where, supervision, and a whole network on loopback."""

from __future__ import annotations

import io
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Callable
from pathlib import Path

import orjson
import pytest

from openptrack_py.config import load_network
from openptrack_py.launch import NodeSpec, Supervisor, host_matches, plan_nodes, this_host
from tests.conftest import ROOT, demo_network_file, free_port, python_env, wait_for

DEMO = ROOT / "config" / "demo.yaml"


# ---------------------------------------------------------------------- planning


def test_demo_runs_the_simulator_on_this_host() -> None:
    cfg = load_network(DEMO)
    specs = plan_nodes(cfg, this_host(), DEMO, ["--log-level", "debug"])
    assert [s.name for s in specs] == ["sim", "tracker", "output"]
    assert specs[0].command()[1:] == [
        "-m", "openptrack_py.nodes.sim", "-c", str(DEMO), "--log-level", "debug",
    ]  # fmt: skip
    assert plan_nodes(cfg, "some-other-machine", DEMO) == []


def test_multi_host_file_assigns_nodes_by_host() -> None:
    path = ROOT / "config" / "multi_host.yaml"
    cfg = load_network(path)
    assert [s.name for s in plan_nodes(cfg, "master", path)] == ["tracker", "output", "record"]
    # each sensor machine runs its camera's detector
    assert [s.name for s in plan_nodes(cfg, "sensor-pc-1", path)] == ["detector_north"]
    assert [s.name for s in plan_nodes(cfg, "sensor-pc-2", path)] == ["detector_south"]


@pytest.mark.parametrize(
    ("configured", "host", "expected"),
    [
        ("localhost", "localhost", True),
        ("localhost", this_host(), True),
        ("127.0.0.1", this_host(), True),
        ("localhost", "elsewhere", False),
        ("master", "master", True),
        ("master", "localhost", False),
    ],
    ids=["local", "own-name", "loopback", "other", "named", "named-vs-local"],
)
def test_host_matching(configured: str, host: str, expected: bool) -> None:
    assert host_matches(configured, host) is expected


# -------------------------------------------------------------------- supervisor


def _crasher(name: str, code: int, delay: float = 0.1, *, finite: bool = False) -> NodeSpec:
    return NodeSpec(name, "tests.procs.crasher", (str(code), str(delay)), finite=finite)


def test_crashed_node_is_restarted_with_backoff() -> None:
    out = io.StringIO()
    sup = Supervisor(
        [_crasher("bad", 3), _crasher("good", 0, finite=True), _crasher("quits", 0)],
        out=out,
        backoff_s=(0.2, 0.4),
        env={"PYTHONPATH": str(ROOT)},
    )
    assert sup.run(duration_s=3.0) == 0
    text = out.getvalue()
    assert "[bad] crasher up, will exit 3" in text
    assert "[launch] bad exited with code 3; restarting in 0.2 s" in text
    assert "restarting in 0.4 s" in text  # doubled
    assert "restarting in 0.8 s" not in text  # capped
    assert text.count("[good] crasher up") == 1  # a finite node's clean exit: its work is done
    assert "[launch] good finished" in text
    # any other node is restarted however it exits
    assert "[launch] quits exited with code 0; restarting in 0.2 s" in text
    assert text.count("[quits] crasher up") >= 2
    bad = next(c for c in sup.children if c.spec.name == "bad")
    assert bad.restarts >= 3


def test_a_node_stopped_by_anyone_but_the_launcher_is_restarted() -> None:
    out = io.StringIO()
    sup = Supervisor([_crasher("tracker", 0, 60.0)], out=out, backoff_s=(0.2, 0.4),
                     env={"PYTHONPATH": str(ROOT)})  # fmt: skip
    runner = threading.Thread(target=sup.run, kwargs={"duration_s": 20.0})
    runner.start()
    try:
        wait_for(lambda: "tracker" in sup.pids(), 10, "the node")
        first = sup.pids()["tracker"]
        os.kill(first, signal.SIGTERM)  # an operator's kill, a stray SIGTERM
        wait_for(lambda: sup.pids().get("tracker", first) != first, 10, "a restart")
    finally:
        sup.request_stop()
        runner.join(30)
    assert "[launch] tracker was stopped by signal 15; restarting in 0.2 s" in out.getvalue()


def test_supervisor_stops_when_every_node_finished() -> None:
    out = io.StringIO()
    sup = Supervisor([_crasher("once", 0, finite=True)], out=out, env={"PYTHONPATH": str(ROOT)})
    assert sup.run(duration_s=60.0) == 0
    assert "[launch] once finished" in out.getvalue()


def test_stop_escalates_to_kill_for_a_node_that_ignores_sigint() -> None:
    out = io.StringIO()
    sup = Supervisor(
        [NodeSpec("stuck", "tests.procs.stubborn")],
        out=out,
        stop_timeout_s=0.5,
        env={"PYTHONPATH": str(ROOT)},
    )
    assert sup.run(duration_s=1.5) == 0
    assert "[stuck] stubborn up" in out.getvalue()
    assert "[launch] stuck did not stop; killing it" in out.getvalue()
    assert sup.pids() == {}


class _ClosedAfterStart(io.StringIO):
    """Output that breaks (a closed terminal) when the stop is announced."""

    def write(self, text: str) -> int:
        if "stopping all nodes" in text:
            raise BrokenPipeError("the terminal is gone")
        return super().write(text)


def test_nodes_are_stopped_even_when_announcing_the_stop_fails() -> None:
    sup = Supervisor([_crasher("tracker", 0, 60.0)], out=_ClosedAfterStart(),
                     env={"PYTHONPATH": str(ROOT)})  # fmt: skip
    pids: list[int] = []

    def signal_once_up() -> None:
        wait_for(lambda: "tracker" in sup.pids(), 10, "the node")
        pids.append(sup.pids()["tracker"])
        sup._stop.from_signal(signal.SIGTERM)  # what the installed handler does

    threading.Thread(target=signal_once_up, daemon=True).start()
    with pytest.raises(BrokenPipeError):
        sup.run(duration_s=30.0)
    assert sup.pids() == {} and len(pids) == 1
    with pytest.raises(ProcessLookupError):
        os.kill(pids[0], 0)  # stopped and reaped


# ---------------------------------------------------------------- whole network


def _cli(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "openptrack_py.cli", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=python_env(),
        cwd=ROOT,
    )


@pytest.mark.zenoh
@pytest.mark.parametrize("stop_signal", [signal.SIGINT, signal.SIGTERM], ids=["sigint", "sigterm"])
def test_launch_runs_the_network_and_stops_cleanly(
    tmp_path: Path, spawn: Callable[..., subprocess.Popen[str]], stop_signal: signal.Signals
) -> None:
    hub = f"tcp/127.0.0.1:{free_port()}"
    net = demo_network_file(tmp_path, hub)
    launcher = spawn("-m", "openptrack_py.cli", "launch", str(net), "--status-interval", "1")
    log = Path(launcher.log_path)  # type: ignore[attr-defined]
    wait_for(lambda: "playing scenario" in log.read_text(), 30, "the sim node to start")

    echo = _cli("echo", "opt/default/detections/**", "-c", str(net), "-n", "6")
    assert echo.returncode == 0, echo.stderr
    lines = [orjson.loads(x) for x in echo.stdout.splitlines()]
    assert len(lines) == 6
    assert {x["key"] for x in lines} <= {f"opt/default/detections/k2_{c}" for c in "abc"}
    assert all(x["msg"]["kind"] == "detections" for x in lines)

    status = _cli("status", "-c", str(net), "--format", "json")
    assert status.returncode == 0, status.stderr
    rows = orjson.loads(status.stdout.splitlines()[-1])
    sim = next(r for r in rows if r["node"] == "sim")
    assert sim["alive"] and sim["out_hz"] > 50  # three sensors at 30 Hz plus ground truth
    sim_pid = sim["pid"]

    wait_for(
        lambda: any("sim out" in x for x in log.read_text().splitlines() if "[status]" in x),
        15,
        "a status line",
    )
    launcher.send_signal(stop_signal)
    assert launcher.wait(timeout=20) == 0
    text = log.read_text()
    assert "stopping all nodes" in text and "INFO sim: stopped" in text
    with pytest.raises(ProcessLookupError):
        os.kill(sim_pid, 0)  # no orphan left behind


@pytest.mark.zenoh
def test_launch_duration_stops_by_itself(tmp_path: Path) -> None:
    net = demo_network_file(tmp_path, f"tcp/127.0.0.1:{free_port()}")
    result = _cli("launch", str(net), "--duration", "3", "--status-interval", "0", timeout=60)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "[launch] duration of 3 s reached" in result.stdout
    assert "[sim]" in result.stdout and "INFO sim: stopped" in result.stdout


@pytest.mark.zenoh
def test_launch_with_a_bad_network_file_names_the_key(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("sim: {scenario: crowd, sed: 3}\n")
    result = _cli("launch", str(bad))
    assert result.returncode == 2
    assert "sim.sed: unknown key; did you mean 'seed'?" in result.stderr
