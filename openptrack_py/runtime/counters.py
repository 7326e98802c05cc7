"""Thread-safe counters and stage timings, turned into :class:`NodeStats` snapshots."""

from __future__ import annotations

import os
import socket
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from openptrack_py.messages.stats import NodeStats

STANDARD_COUNTERS = ("in", "out", "dropped", "malformed")


class Counters:
    """Monotonic event counters and per-stage timings of one node.

    The four standard counters (``in``, ``out``, ``dropped``, ``malformed``) always
    exist; nodes may add their own names.

    Parameters
    ----------
    node : str
        Node name put in every snapshot.
    clock : callable
        Wall-clock time source (injectable for tests).
    """

    def __init__(self, node: str, clock: Callable[[], float] = time.time) -> None:
        self.node = node
        self.clock = clock
        self.started = clock()
        self._counts: dict[str, int] = dict.fromkeys(STANDARD_COUNTERS, 0)
        self._timing_sum: dict[str, float] = {}
        self._timing_n: dict[str, int] = {}
        self._last_counts = dict(self._counts)
        self._last_time = self.started
        self._lock = threading.Lock()

    def inc(self, name: str, n: int = 1) -> None:
        """Add ``n`` to counter ``name``."""
        with self._lock:
            self._counts[name] = self._counts.get(name, 0) + n

    def get(self, name: str) -> int:
        """Current value of counter ``name`` (0 if never incremented)."""
        with self._lock:
            return self._counts.get(name, 0)

    def add_timing(self, stage: str, seconds: float) -> None:
        """Record one duration of ``stage``."""
        with self._lock:
            self._timing_sum[stage] = self._timing_sum.get(stage, 0.0) + seconds
            self._timing_n[stage] = self._timing_n.get(stage, 0) + 1

    @contextmanager
    def timed(self, stage: str) -> Iterator[None]:
        """Time the ``with`` block as one run of ``stage``."""
        start = time.perf_counter()
        try:
            yield
        finally:
            self.add_timing(stage, time.perf_counter() - start)

    def snapshot(self) -> NodeStats:
        """Totals, rates since the previous snapshot, and mean stage timings."""
        now = self.clock()
        with self._lock:
            counts = dict(self._counts)
            dt = max(now - self._last_time, 1e-9)
            rates = {
                k: round((v - self._last_counts.get(k, 0)) / dt, 3) for k, v in counts.items()
            }
            timings = {
                k: round(1e3 * self._timing_sum[k] / n, 4) for k, n in self._timing_n.items() if n
            }
            self._last_counts = counts
            self._last_time = now
            self._timing_sum.clear()
            self._timing_n.clear()
        return NodeStats(
            node=self.node,
            stamp=now,
            uptime_s=round(now - self.started, 3),
            counters=counts,
            rates_hz=rates,
            timings_ms=timings,
            pid=os.getpid(),
            host=socket.gethostname(),
        )
