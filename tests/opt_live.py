"""A live sim -> tracker -> output network for the client tests, and datagram capture.

:class:`LiveNetwork` writes a network file (the ``crowd`` scenario on its own three
simulated sensors, a tracker, one output node with the sinks a test asks for), starts it
with ``openptrack launch`` on a fresh hub port with multicast scouting off, and collects
every datagram the output node sends to the test's UDP sockets.
"""

from __future__ import annotations

import contextlib
import selectors
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.conftest import ROOT, free_port, python_env


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that was free a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def multicast_works(group: str = "224.0.0.1") -> bool:
    """Whether a datagram sent to ``group`` comes back to this host (needs a route)."""
    port = free_udp_port()
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        rx.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        rx.bind(("", port))
        rx.setsockopt(
            socket.IPPROTO_IP,
            socket.IP_ADD_MEMBERSHIP,
            struct.pack("4s4s", socket.inet_aton(group), socket.inet_aton("0.0.0.0")),
        )
        rx.settimeout(1.0)
        tx.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
        tx.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
        tx.sendto(b"probe", (group, port))
        return rx.recvfrom(64)[0] == b"probe"
    except OSError:
        return False
    finally:
        rx.close()
        tx.close()


class Capture:
    """Datagrams received on one bound UDP socket, with their arrival times."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.setblocking(False)
        self.port: int = self.sock.getsockname()[1]
        self._items: list[tuple[float, bytes]] = []
        self._lock = threading.Lock()

    def add(self, data: bytes) -> None:
        with self._lock:
            self._items.append((time.time(), data))

    def timed(self) -> list[tuple[float, bytes]]:
        """``(arrival time, datagram)`` in arrival order."""
        with self._lock:
            return list(self._items)

    def datagrams(self) -> list[bytes]:
        """The datagrams in arrival order."""
        return [d for _, d in self.timed()]


def is_heartbeat(data: bytes) -> bool:
    """Whether an OpenPTrack datagram is an ``alive_IDs`` heartbeat (by its bytes)."""
    return b'"alive_IDs":' in data


def has_tracks(data: bytes) -> bool:
    """Whether a tracks datagram holds at least one track."""
    return b'"id":' in data and not is_heartbeat(data)


class LiveNetwork:
    """sim + tracker + one output node, started by the launcher, with captured sinks.

    Parameters
    ----------
    workdir : Path
        Where the network file and the launcher's log go.
    udp : dict
        ``name -> UdpSinkConfig fields`` for sinks aimed at a :class:`Capture` of that
        name (host and port are filled in).
    extra_udp : iterable of dict
        Sinks with their own host and port (a receiver outside the test process).
    osc : bool
        Add an OSC sink aimed at the capture named ``"osc"``.
    web : bool
        Serve the WebSocket stream on a free port (:attr:`web_port`).
    seed : int
        Simulator seed.
    """

    def __init__(
        self,
        workdir: Path,
        udp: dict[str, dict[str, Any]],
        *,
        extra_udp: Iterable[dict[str, Any]] = (),
        osc: bool = False,
        web: bool = False,
        seed: int = 3,
    ) -> None:
        self.workdir = workdir
        self.captures = {name: Capture(name) for name in udp}
        if osc:
            self.captures["osc"] = Capture("osc")
        self.hub = f"tcp/127.0.0.1:{free_port()}"
        self.web_port = free_port() if web else None
        sinks = [
            {**fields, "host": "127.0.0.1", "port": self.captures[name].port}
            for name, fields in udp.items()
        ]
        sinks += [dict(s) for s in extra_udp]
        output: dict[str, Any] = {"name": "output", "udp": sinks}
        if osc:
            output["osc"] = [{"host": "127.0.0.1", "port": self.captures["osc"].port}]
        if web:
            output["web"] = {"host": "127.0.0.1", "port": self.web_port, "room": [0, 0, 10, 10]}
        self.network = {
            "site": "default",
            "zenoh": {
                "hub": self.hub,
                "listen": ["tcp/127.0.0.1:0"],
                "multicast_scouting": False,
            },
            "sensors": [],
            "sim": {"scenario": "crowd", "seed": seed, "use_scenario_sensors": True},
            "tracker": {},
            "outputs": [output],
        }
        self.path = workdir / "net.yaml"
        self.path.write_text(yaml.safe_dump(self.network, sort_keys=False))
        self.log_path = workdir / "launch.log"
        self.proc: subprocess.Popen[str] | None = None
        self._stop = threading.Event()
        self._reader = threading.Thread(target=self._read, name="capture", daemon=True)

    # ---------------------------------------------------------------- lifecycle

    def _read(self) -> None:
        sel = selectors.DefaultSelector()
        for cap in self.captures.values():
            sel.register(cap.sock, selectors.EVENT_READ, cap)
        while not self._stop.is_set():
            for key, _ in sel.select(timeout=0.05):
                cap: Capture = key.data
                while True:
                    try:
                        data = cap.sock.recv(65535)
                    except (BlockingIOError, InterruptedError):
                        break
                    except OSError:
                        return
                    cap.add(data)
        sel.close()

    def start(self) -> LiveNetwork:
        """Start capturing, then the launcher."""
        self._reader.start()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "openptrack_py.cli", "launch", str(self.path),
             "--status-interval", "0"],
            stdout=self.log_path.open("w"), stderr=subprocess.STDOUT, text=True,
            env=python_env(), cwd=ROOT,
        )  # fmt: skip
        return self

    def log(self) -> str:
        """What the launcher and its nodes printed so far."""
        return self.log_path.read_text() if self.log_path.exists() else ""

    def wait(self, predicate: Callable[[], bool], timeout_s: float, what: str) -> None:
        """Poll ``predicate``; fail with the launcher's log after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if predicate():
                return
            if self.proc is not None and self.proc.poll() is not None:
                pytest.fail(f"the launcher exited early:\n{self.log()[-3000:]}")
            time.sleep(0.05)
        pytest.fail(f"timed out after {timeout_s} s waiting for {what}:\n{self.log()[-3000:]}")

    def wait_for_frames(self, name: str, count: int, timeout_s: float = 40.0) -> None:
        """Wait until capture ``name`` holds ``count`` datagrams with tracks."""
        cap = self.captures[name]
        self.wait(
            lambda: sum(has_tracks(d) for d in cap.datagrams()) >= count,
            timeout_s,
            f"{count} frames with tracks on {name}",
        )

    def stop(self) -> None:
        """Stop the launcher (SIGINT, then SIGKILL) and the capture."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._stop.set()
        if self._reader.is_alive():
            self._reader.join(timeout=2)
        for cap in self.captures.values():
            with contextlib.suppress(OSError):
                cap.sock.close()

    def __enter__(self) -> LiveNetwork:
        return self.start()

    def __exit__(self, *_exc: object) -> None:
        self.stop()


def run_node(script: str, stdin: str = "", timeout_s: float = 30.0) -> str:
    """Run JavaScript under ``node``; return its stdout (fails the test on an error)."""
    result = subprocess.run(
        ["node", "-e", script],
        input=stdin,
        capture_output=True,
        text=True,
        timeout=timeout_s,
        cwd=ROOT,
    )
    assert result.returncode == 0, result.stderr
    return result.stdout
