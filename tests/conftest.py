"""Shared fixtures: hypothesis profiles, free loopback ports, Zenoh settings, subprocesses.

Hypothesis profiles, chosen with the ``HYPOTHESIS_PROFILE`` environment variable (or
pytest's ``--hypothesis-profile``):

``dev`` (default)
    Random examples, remembered in ``.hypothesis/``; a failure prints the falsifying example
    and a ``@reproduce_failure(...)`` line that replays it anywhere.
``ci``
    Derandomized: the same examples on every run (``.ci/run`` selects it), so a red CI run
    is red again on a laptop with ``HYPOTHESIS_PROFILE=ci``; failures print the blob too.

Neither sets a per-example deadline: tests never assert wall-clock times.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

from openptrack_py.config import ZenohConfig
from openptrack_py.runtime.ports import free_port  # also imported from here by tests
from openptrack_py.sim.world import Snapshot

ROOT = Path(__file__).resolve().parent.parent
PROCS = Path(__file__).resolve().parent / "procs"

settings.register_profile("dev", deadline=None, print_blob=True)
settings.register_profile(
    "ci",
    derandomize=True,
    max_examples=100,
    deadline=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],  # shared CI machines are slow at times
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "dev"))


def pytest_report_header(config: pytest.Config) -> str | None:
    """Name the hypothesis profile in the header (hypothesis itself does only with -v)."""
    if config.option.verbose >= 1:
        return None
    return f"hypothesis profile {settings.get_current_profile_name()!r} (HYPOTHESIS_PROFILE)"


@pytest.fixture
def hub_endpoint() -> str:
    """A fresh loopback endpoint for a test's Zenoh hub."""
    return f"tcp/127.0.0.1:{free_port()}"


@pytest.fixture
def zenoh_cfg(hub_endpoint: str) -> ZenohConfig:
    """Peer mode, multicast scouting off, everyone meeting at this test's hub."""
    return ZenohConfig(hub=hub_endpoint, listen=["tcp/127.0.0.1:0"], multicast_scouting=False)


def python_env() -> dict[str, str]:
    """Environment for child Python processes (unbuffered, Zenoh quiet)."""
    return {**os.environ, "PYTHONUNBUFFERED": "1", "RUST_LOG": "error"}


@pytest.fixture
def spawn(tmp_path: Path) -> Iterator[Callable[..., subprocess.Popen[str]]]:
    """Start child processes whose output goes to files; kill leftovers at the end."""
    procs: list[subprocess.Popen[str]] = []

    def start(*args: str, name: str = "proc") -> subprocess.Popen[str]:
        out = (tmp_path / f"{name}-{len(procs)}.log").open("w")
        proc = subprocess.Popen(
            [sys.executable, *args],
            stdout=out,
            stderr=subprocess.STDOUT,
            text=True,
            env=python_env(),
            cwd=ROOT,
        )
        proc.log_path = Path(out.name)  # type: ignore[attr-defined]
        procs.append(proc)
        return proc

    yield start
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def start_tracker(net: Path, endpoint: str, log: Path) -> subprocess.Popen[str]:
    """The tracker node of network file ``net`` as a real process listening on ``endpoint``."""
    return subprocess.Popen(
        [sys.executable, "-m", "openptrack_py.nodes.tracker", "-c", str(net), "-l", endpoint,
         "--no-multicast-scouting"],
        stdout=log.open("w"), stderr=subprocess.STDOUT, text=True, env=python_env(), cwd=ROOT,
    )  # fmt: skip


def stop_process(*procs: subprocess.Popen[str], timeout_s: float = 15.0) -> None:
    """Ask running processes to stop (SIGINT, as Ctrl-C), then kill those still there."""
    running = [p for p in procs if p.poll() is None]
    for proc in running:
        proc.send_signal(signal.SIGINT)
    for proc in running:
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def wait_for(predicate: Callable[[], bool], timeout_s: float = 15.0, what: str = "") -> None:
    """Poll ``predicate`` until it holds; fail the test after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.05)
    pytest.fail(f"timed out after {timeout_s} s waiting for {what or predicate}")


def people_snapshot(
    people: Sequence[tuple[float, ...]],
    *,
    t: float = 0.0,
    vel: np.ndarray | None = None,
    kind: str = "adult",
) -> Snapshot:
    """A world snapshot of people given as ``(x, y, height, radius, top_hue, bottom_hue)``."""
    rows = np.array(people, dtype=float).reshape(-1, 6)
    n = len(rows)
    return Snapshot(
        t=t,
        ids=np.arange(1, n + 1),
        kinds=np.array([kind] * n, dtype="<U5"),
        pos=rows[:, :2].copy(),
        vel=np.zeros((n, 2)) if vel is None else np.asarray(vel, dtype=float).reshape(n, 2),
        height=rows[:, 2].copy(),
        radius=rows[:, 3].copy(),
        top_hue=rows[:, 4].copy(),
        bottom_hue=rows[:, 5].copy(),
    )


def demo_network_file(tmp_path: Path, hub: str, **sections: dict) -> Path:
    """The demo network with ``hub``, free output ports and ``sections`` merged in."""
    import yaml

    data = yaml.safe_load((ROOT / "config" / "demo.yaml").read_text())
    data["zenoh"]["hub"] = hub
    for name, changes in sections.items():
        data[name].update(changes)
    for out in data.get("outputs", []):  # free ports, so parallel runs never collide
        out["web"]["port"] = 0
        for udp in out["udp"]:
            udp["port"] = free_port()
    path = tmp_path / "net.yaml"
    path.write_text(yaml.safe_dump(data))
    return path
