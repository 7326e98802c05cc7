"""What every node process shares: liveliness, counters, stats, bad-input handling, shutdown.

A node receives through :meth:`Node.subscribe`, which decodes on the transport thread:
a message that fails to decode is counted as ``malformed``, logged (rate-limited) and
dropped, and the node goes on. Decoded messages wait in a bounded :class:`Inbox` for the
node's own loop; when the loop falls behind, the oldest are dropped and counted.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from openptrack_py.errors import WireFormatError
from openptrack_py.messages.codec import encode_node_stats
from openptrack_py.runtime.counters import Counters
from openptrack_py.runtime.logs import RateLimitedLog
from openptrack_py.runtime.memory import release_memory
from openptrack_py.runtime.stop import StopRequest
from openptrack_py.transport.base import Bus, Closable, Publisher, Sample
from openptrack_py.transport.keys import SiteKeys

T = TypeVar("T")
log = logging.getLogger(__name__)

RELEASE_MEMORY_EVERY_S = 10.0
"""How often a node gives free heap memory back to the operating system."""


@dataclass(frozen=True, slots=True)
class Received(Generic[T]):
    """A decoded message and where and when it arrived.

    Parameters
    ----------
    key : str
        Key it was published on.
    message : T
        The decoded message.
    received : float
        Local arrival time, UNIX seconds.
    """

    key: str
    message: T
    received: float


class Inbox(Generic[T]):
    """A bounded, thread-safe queue that drops its oldest item when full.

    Parameters
    ----------
    maxsize : int
        Capacity; at least 1.
    on_drop : callable, optional
        Called once per dropped item (e.g. to count it).
    """

    def __init__(self, maxsize: int = 1024, on_drop: Callable[[], None] | None = None) -> None:
        if maxsize < 1:
            raise ValueError(f"Inbox: maxsize must be >= 1, got {maxsize}")
        self._items: deque[T] = deque()
        self._maxsize = maxsize
        self._on_drop = on_drop
        self._cond = threading.Condition()

    def __len__(self) -> int:
        with self._cond:
            return len(self._items)

    def push(self, item: T) -> None:
        """Append ``item``, dropping the oldest if full."""
        dropped = False
        with self._cond:
            if len(self._items) >= self._maxsize:
                self._items.popleft()
                dropped = True
            self._items.append(item)
            self._cond.notify()
        if dropped and self._on_drop is not None:
            self._on_drop()

    def get(self, timeout: float | None = None) -> T | None:
        """Next item, waiting up to ``timeout`` seconds; ``None`` if none came."""
        with self._cond:
            if not self._items and not self._cond.wait_for(lambda: bool(self._items), timeout):
                return None
            return self._items.popleft()

    def drain(self, timeout: float | None = None) -> list[T]:
        """Every queued item (waiting up to ``timeout`` for the first one)."""
        with self._cond:
            if not self._items:
                self._cond.wait_for(lambda: bool(self._items), timeout)
            items = list(self._items)
            self._items.clear()
            return items


class _CountingPublisher:
    def __init__(self, inner: Publisher, counters: Counters) -> None:
        self._inner = inner
        self._counters = counters
        self.key = inner.key

    def put(self, payload: bytes) -> None:
        self._inner.put(payload)
        self._counters.inc("out")

    def has_subscribers(self) -> bool:
        return self._inner.has_subscribers()

    def close(self) -> None:
        self._inner.close()


class Node:
    """The runtime of one node process.

    Parameters
    ----------
    name : str
        Node name: its liveliness token is ``opt/<site>/alive/<name>`` and its stats go
        to ``opt/<site>/stats/<name>``.
    bus : Bus
        The session to use; the node does not close it.
    site : str
        Site name.
    stats_interval_s : float
        Period of stats publication; 0 disables it.
    """

    def __init__(
        self, name: str, bus: Bus, *, site: str = "default", stats_interval_s: float = 2.0
    ) -> None:
        self.name = name
        self.bus = bus
        self.keys = SiteKeys(site)
        self.counters = Counters(name)
        self.log = logging.getLogger(f"openptrack.{name}")
        self.bad_input = RateLimitedLog(self.log, interval_s=5.0)
        self.stats_interval_s = stats_interval_s
        self._stop = StopRequest(on_signal=self._log_signal)
        self._declared: list[Closable] = []
        self._stats_thread: threading.Thread | None = None
        self._stats_pub: Publisher | None = None
        self._started = False

    # ------------------------------------------------------------------ lifecycle

    def __enter__(self) -> Node:
        self.start()
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def start(self) -> None:
        """Announce liveliness and start publishing stats."""
        if self._started:
            return
        self._started = True
        self._declared.append(self.bus.declare_token(self.keys.alive(self.name)))
        if self.stats_interval_s > 0:
            self._stats_pub = self.bus.publisher(self.keys.stats(self.name), reliable=False)
            self._stats_thread = threading.Thread(
                target=self._stats_loop, name=f"{self.name}-stats", daemon=True
            )
            self._stats_thread.start()
        self.log.info("started", extra={"fields": {"site": self.keys.site}})

    @property
    def running(self) -> bool:
        """``False`` once :meth:`stop` was called (e.g. by SIGINT or SIGTERM)."""
        return not self._stop.is_set()

    def stop(self) -> None:
        """Ask the node's loop to finish."""
        self._stop.set()

    def wait(self, timeout: float | None = None) -> bool:
        """Sleep until stopped or ``timeout``; return whether the node was stopped."""
        return self._stop.wait(timeout)

    def install_signal_handlers(self) -> None:
        """Make SIGINT and SIGTERM stop the node cleanly (main thread only)."""
        self._stop.install()

    def _log_signal(self, name: str) -> None:
        self.log.info("stopping", extra={"fields": {"signal": name}})

    def close(self) -> None:
        """Stop, publish final stats, undeclare everything declared through the node."""
        self.stop()
        if self._stats_thread is not None:
            self._stats_thread.join(timeout=2.0)
            self._stats_thread = None
            self.publish_stats()
        for item in reversed(self._declared):
            item.close()
        self._declared.clear()
        if self._started:
            self.log.info("stopped", extra={"fields": self.counters.snapshot().counters})
            self._started = False

    # -------------------------------------------------------------------- traffic

    def publisher(self, key: str, *, reliable: bool = True) -> Publisher:
        """Declare a publisher whose puts count as ``out``."""
        pub = _CountingPublisher(self.bus.publisher(key, reliable=reliable), self.counters)
        self._declared.append(pub)
        return pub

    def subscribe(
        self,
        keyexpr: str,
        decode: Callable[[bytes], T],
        inbox: Inbox[Received[T]] | None = None,
        maxsize: int = 1024,
    ) -> Inbox[Received[T]]:
        """Decode every sample on ``keyexpr`` into ``inbox`` (a new one by default).

        Valid messages count as ``in``; undecodable ones as ``malformed`` (logged,
        rate-limited, then dropped); messages pushed out of a full inbox as ``dropped``.
        """
        if inbox is None:
            inbox = Inbox(maxsize, on_drop=lambda: self.counters.inc("dropped"))

        def on_sample(sample: Sample) -> None:
            try:
                message = decode(sample.payload)
            except WireFormatError as exc:
                self.reject(sample.key, exc)
                return
            self.counters.inc("in")
            inbox.push(Received(sample.key, message, time.time()))

        self._declared.append(self.bus.subscribe(keyexpr, on_sample))
        return inbox

    def reject(self, key: str, error: Exception) -> None:
        """Count and log (rate-limited) one undecodable message."""
        self.counters.inc("malformed")
        self.bad_input.warning(
            f"malformed:{key}", "dropped malformed message", key=key, error=str(error)[:200]
        )

    def declare(self, item: Closable) -> Closable:
        """Close ``item`` when the node closes."""
        self._declared.append(item)
        return item

    # ---------------------------------------------------------------------- stats

    def publish_stats(self) -> None:
        """Publish one stats snapshot now."""
        if self._stats_pub is None:
            return
        try:
            self._stats_pub.put(encode_node_stats(self.counters.snapshot()))
        except Exception:  # stats must never take a node down
            log.debug("stats publication failed", exc_info=True)

    def _stats_loop(self) -> None:
        last_release = time.monotonic()
        while not self._stop.wait(self.stats_interval_s):
            self.publish_stats()
            if time.monotonic() - last_release >= RELEASE_MEMORY_EVERY_S:
                last_release = time.monotonic()
                release_memory()


def run_until_stopped(node: Node, step: Callable[[], Any], idle_s: float = 0.05) -> None:
    """Call ``step`` until the node stops; sleep ``idle_s`` when it returns falsy."""
    while node.running:
        if not step():
            node.wait(idle_s)
