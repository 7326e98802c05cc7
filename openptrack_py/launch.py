"""Start the nodes a network file asks for on this host, and keep them running.

:func:`plan_nodes` decides which node processes belong on a host (a pure function of the
network file). :class:`Supervisor` runs them as subprocesses: it prefixes each line they
print with the node's name, restarts a node that crashed (exponential back-off, reset
once it has stayed up a while), and on Ctrl-C, SIGTERM or the end of ``--duration``
stops them all: SIGINT first, SIGKILL after a grace period.

The launcher on the network's ``hub_host`` also opens the Zenoh session every node
connects to (the hub), and prints a one-line summary of the nodes' stats now and then.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from openptrack_py.config import NetworkConfig
from openptrack_py.config.network import (
    CALIBRATION,
    RECORDER,
    SIM,
    TRACKER,
    detector_node_name,
)
from openptrack_py.runtime.stop import StopRequest

LOCAL_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})


@dataclass(frozen=True)
class NodeSpec:
    """One node process to run.

    Parameters
    ----------
    name : str
        Node name (also its log prefix).
    module : str
        Module run with ``python -m``.
    args : tuple of str
        Its command-line arguments.
    finite : bool
        The node may finish its work (a sensor replaying a recording, a simulation with
        a duration): a clean exit ends it. Any other node is restarted whenever it
        exits, clean or not, unless the launcher asked it to stop (a stray SIGTERM, an
        operator's ``kill``, a crash: the installation keeps running).
    """

    name: str
    module: str
    args: tuple[str, ...] = ()
    finite: bool = False

    def command(self) -> list[str]:
        """The full command line."""
        return [sys.executable, "-m", self.module, *self.args]


def this_host() -> str:
    """Return the host name of this machine."""
    return socket.gethostname()


def host_matches(configured: str, host: str) -> bool:
    """Whether a node configured for ``configured`` runs on ``host``.

    ``localhost`` (and loopback addresses) mean "the machine running the launcher" when
    the launcher runs for this machine's own name or for ``localhost``.
    """
    if configured == host:
        return True
    return configured in LOCAL_NAMES and (host in LOCAL_NAMES or host == this_host())


def plan_nodes(
    cfg: NetworkConfig,
    host: str,
    config_path: str | Path,
    extra_args: Sequence[str] = (),
) -> list[NodeSpec]:
    """The node processes ``host`` runs for this network.

    Parameters
    ----------
    cfg : NetworkConfig
        The validated network file.
    host : str
        Host name the launcher runs for.
    config_path : str or Path
        The network file, passed on to every node with ``-c``.
    extra_args : sequence of str
        Further arguments for every node (``--set`` overrides, logging flags).
    """
    common = ("-c", str(config_path), *extra_args)
    specs: list[NodeSpec] = []
    simulated = [s for s in cfg.sensors if s.source == "sim"]
    wants_sim = simulated or (cfg.sim is not None and cfg.sim.use_scenario_sensors)
    if cfg.sim is not None and host_matches(cfg.sim.host, host) and (wants_sim or not cfg.sensors):
        finite = cfg.sim.duration_s is not None
        specs.append(NodeSpec(SIM, "openptrack_py.nodes.sim", common, finite=finite))
    rgbd = cfg.sim is not None and cfg.sim.sensor_model == "rgbd"
    for sensor in cfg.sensors:
        # A detector per real sensor on its own machine, and per rendered sensor on the
        # simulator's machine.
        if sensor.source == "sim":
            runs_here = rgbd and host_matches(cfg.sim.host, host)  # type: ignore[union-attr]
        else:
            runs_here = host_matches(sensor.host, host)
        if runs_here:
            name = detector_node_name(sensor.id)
            args = (*common, "--sensor", sensor.id, "--name", name)
            finite = sensor.source == "recording"
            specs.append(NodeSpec(name, "openptrack_py.nodes.detector", args, finite=finite))
    if cfg.tracker is not None and host_matches(cfg.tracker.host, host):
        specs.append(NodeSpec(TRACKER, "openptrack_py.nodes.tracker", common))
    master = cfg.tracker.host if cfg.tracker is not None else "localhost"
    if cfg.calibrated and host_matches(master, host):
        specs.append(NodeSpec(CALIBRATION, "openptrack_py.nodes.calibration", common))
    for out in cfg.outputs:
        if host_matches(out.host, host):
            specs.append(
                NodeSpec(out.name, "openptrack_py.nodes.output", (*common, "--name", out.name))
            )
    if cfg.recorder is not None and host_matches(cfg.recorder.host, host):
        specs.append(NodeSpec(RECORDER, "openptrack_py.nodes.record", common))
    return specs


@dataclass
class _Child:
    spec: NodeSpec
    process: subprocess.Popen[str] | None = None
    started: float = 0.0
    restarts: int = 0
    backoff_s: float = 1.0
    restart_at: float | None = None
    finished: bool = False
    reader: threading.Thread | None = field(default=None, repr=False)


def _set_parent_death_signal() -> None:  # pragma: no cover - runs in the child
    # Linux: the child gets SIGTERM if the launcher dies, so no node is orphaned.
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except Exception:
        pass


class Supervisor:
    """Runs node processes, prefixes their output, restarts crashed ones.

    Parameters
    ----------
    specs : sequence of NodeSpec
        The nodes.
    out : text stream
        Where prefixed output goes.
    backoff_s : tuple of float
        First and largest restart delay, seconds.
    stable_after_s : float
        A node that ran this long before crashing restarts after the first delay again.
    stop_timeout_s : float
        Grace period between SIGINT and SIGKILL when stopping.
    env : dict, optional
        Environment of the children.
    """

    def __init__(
        self,
        specs: Sequence[NodeSpec],
        *,
        out: IO[str] | None = None,
        backoff_s: tuple[float, float] = (1.0, 30.0),
        stable_after_s: float = 30.0,
        stop_timeout_s: float = 5.0,
        env: dict[str, str] | None = None,
    ) -> None:
        self.children = [_Child(spec, backoff_s=backoff_s[0]) for spec in specs]
        self.out = out if out is not None else sys.stdout
        self.backoff_s = backoff_s
        self.stable_after_s = stable_after_s
        self.stop_timeout_s = stop_timeout_s
        self.env = {**os.environ, "PYTHONUNBUFFERED": "1", **(env or {})}
        self._lock = threading.Lock()
        self._stop = StopRequest(
            on_signal=lambda name: self.say("launch", f"{name}: stopping all nodes")
        )

    def say(self, name: str, line: str) -> None:
        """Print one prefixed line."""
        with self._lock:
            self.out.write(f"[{name}] {line.rstrip()}\n")
            self.out.flush()

    def say_raw(self, text: str) -> None:
        """Write ``text`` as it is (for a table repainted in place)."""
        with self._lock:
            self.out.write(text)
            self.out.flush()

    def _pump(self, child: _Child, stream: IO[str]) -> None:
        for line in stream:
            self.say(child.spec.name, line)

    def _start(self, child: _Child) -> None:
        child.process = subprocess.Popen(
            child.spec.command(),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            text=True,
            bufsize=1,
            env=self.env,
            start_new_session=True,  # Ctrl-C reaches the launcher, which stops children in order
            preexec_fn=_set_parent_death_signal if sys.platform == "linux" else None,
        )
        child.started = time.monotonic()
        child.restart_at = None
        assert child.process.stdout is not None
        child.reader = threading.Thread(
            target=self._pump, args=(child, child.process.stdout), daemon=True
        )
        child.reader.start()

    def _check(self, child: _Child, now: float) -> None:
        if child.finished:
            return
        if child.process is None:
            if child.restart_at is not None and now >= child.restart_at:
                child.restarts += 1
                self.say("launch", f"restarting {child.spec.name} (restart #{child.restarts})")
                self._start(child)
            return
        code = child.process.poll()
        if code is None:
            return
        if child.reader is not None:
            child.reader.join(timeout=1.0)
        child.process = None
        if code == 0 and child.spec.finite:
            self.say("launch", f"{child.spec.name} finished")
            child.finished = True
            return
        if now - child.started >= self.stable_after_s:
            child.backoff_s = self.backoff_s[0]
        delay = child.backoff_s
        child.backoff_s = min(child.backoff_s * 2, self.backoff_s[1])
        child.restart_at = now + delay
        how = f"was stopped by signal {-code}" if code < 0 else f"exited with code {code}"
        self.say("launch", f"{child.spec.name} {how}; restarting in {delay:g} s")

    def request_stop(self) -> None:
        """Ask :meth:`run` to stop all nodes and return (from another thread)."""
        self._stop.set()

    def install_signal_handlers(self) -> None:
        """Make SIGINT and SIGTERM stop all nodes (main thread only; the handler takes no lock)."""
        self._stop.install()

    def run(self, duration_s: float | None = None) -> int:
        """Start every node and supervise until stopped, the duration ends or all finish.

        Returns 0, or 1 if some node could not be started.
        """
        for child in self.children:
            try:
                self._start(child)
            except OSError as exc:
                self.say("launch", f"cannot start {child.spec.name}: {exc}")
                self.stop_all()
                return 1
        deadline = None if duration_s is None else time.monotonic() + duration_s
        try:  # the nodes are stopped whatever ends the loop (a failed print included)
            while not self._stop.is_set():
                now = time.monotonic()
                if deadline is not None and now >= deadline:
                    self.say("launch", f"duration of {duration_s:g} s reached")
                    break
                for child in self.children:
                    self._check(child, now)
                if self.children and all(c.finished for c in self.children):
                    break
                self._stop.wait(0.1)
        finally:
            self.stop_all()
        return 0

    def stop_all(self) -> None:
        """SIGINT every running node, wait, then SIGKILL what is left."""
        running = [c for c in self.children if c.process is not None]
        for child in running:
            assert child.process is not None
            with contextlib.suppress(ProcessLookupError):
                child.process.send_signal(signal.SIGINT)
        deadline = time.monotonic() + self.stop_timeout_s
        for child in running:
            assert child.process is not None
            try:
                child.process.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                self.say("launch", f"{child.spec.name} did not stop; killing it")
                child.process.kill()
                child.process.wait()
            if child.reader is not None:
                child.reader.join(timeout=1.0)
            child.process = None

    def pids(self) -> dict[str, int]:
        """Process id of every running node."""
        return {c.spec.name: c.process.pid for c in self.children if c.process is not None}
