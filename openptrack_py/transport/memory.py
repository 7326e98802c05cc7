"""In-process bus: deterministic, synchronous, no threads, no sockets.

Every ``put`` calls the matching subscribers before returning, in subscription order.
Several :class:`MemoryBus` objects can share one :class:`MemoryNetwork` to stand for
several processes; liveliness tokens of a closed bus disappear like those of a dead
Zenoh session.
"""

from __future__ import annotations

import itertools
import threading
from dataclasses import dataclass, field

from openptrack_py.transport.base import (
    LivelinessHandler,
    QueryHandler,
    Sample,
    SampleHandler,
)
from openptrack_py.transport.keys import key_matches, validate_key


@dataclass
class _Entry:
    owner: MemoryBus
    expr: str
    handler: object
    closed: bool = False

    def close(self) -> None:
        self.closed = True


@dataclass
class MemoryNetwork:
    """The shared medium of a set of :class:`MemoryBus` instances."""

    subscribers: list[_Entry] = field(default_factory=list)
    liveliness_subscribers: list[_Entry] = field(default_factory=list)
    queryables: list[_Entry] = field(default_factory=list)
    tokens: dict[int, tuple[MemoryBus, str]] = field(default_factory=dict)
    lock: threading.RLock = field(default_factory=threading.RLock)
    _ids: itertools.count = field(default_factory=itertools.count)

    def _live(self, entries: list[_Entry]) -> list[_Entry]:
        alive = [e for e in entries if not e.closed and not e.owner.closed]
        entries[:] = alive
        return list(alive)


class _Token:
    def __init__(self, bus: MemoryBus, key: str) -> None:
        self._bus = bus
        self.key = key
        self._id = next(bus.network._ids)
        with bus.network.lock:
            bus.network.tokens[self._id] = (bus, key)
        bus._notify_liveliness(key, True)

    def close(self) -> None:
        with self._bus.network.lock:
            present = self._bus.network.tokens.pop(self._id, None)
        if present is not None:
            self._bus._notify_liveliness(self.key, False)


class _MemoryPublisher:
    def __init__(self, bus: MemoryBus, key: str) -> None:
        self._bus = bus
        self.key = key

    def put(self, payload: bytes) -> None:
        self._bus.put(self.key, payload)

    def has_subscribers(self) -> bool:
        with self._bus.network.lock:
            entries = self._bus.network._live(self._bus.network.subscribers)
        return any(key_matches(e.expr, self.key) for e in entries)

    def close(self) -> None:
        pass


class MemoryBus:
    """A :class:`~openptrack_py.transport.base.Bus` that never leaves the process.

    Parameters
    ----------
    network : MemoryNetwork, optional
        Share one network between several buses; a private one by default.
    """

    def __init__(self, network: MemoryNetwork | None = None) -> None:
        self.network = network if network is not None else MemoryNetwork()
        self.closed = False

    def __enter__(self) -> MemoryBus:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def publisher(self, key: str, *, reliable: bool = True) -> _MemoryPublisher:
        """Declare a publisher on ``key``."""
        return _MemoryPublisher(self, validate_key(key))

    def put(self, key: str, payload: bytes, *, reliable: bool = True) -> None:
        """Deliver ``payload`` to every matching subscriber, synchronously."""
        if self.closed:
            raise RuntimeError("MemoryBus is closed")
        with self.network.lock:
            entries = self.network._live(self.network.subscribers)
        sample = Sample(key, bytes(payload))
        for entry in entries:
            if key_matches(entry.expr, key):
                entry.handler(sample)  # type: ignore[operator]

    def subscribe(self, keyexpr: str, handler: SampleHandler) -> _Entry:
        """Subscribe ``handler`` to ``keyexpr``."""
        entry = _Entry(self, validate_key(keyexpr, allow_wildcards=True), handler)
        with self.network.lock:
            self.network.subscribers.append(entry)
        return entry

    def declare_token(self, key: str) -> _Token:
        """Announce a liveliness token."""
        return _Token(self, validate_key(key))

    def alive(self, keyexpr: str, timeout_s: float = 1.0) -> list[str]:
        """Keys of live tokens matching ``keyexpr``."""
        with self.network.lock:
            tokens = list(self.network.tokens.values())
        return sorted(key for bus, key in tokens if not bus.closed and key_matches(keyexpr, key))

    def subscribe_liveliness(self, keyexpr: str, handler: LivelinessHandler) -> _Entry:
        """Report token appearances and disappearances, current tokens first."""
        entry = _Entry(self, validate_key(keyexpr, allow_wildcards=True), handler)
        with self.network.lock:
            self.network.liveliness_subscribers.append(entry)
        for key in self.alive(keyexpr):
            handler(key, True)
        return entry

    def _notify_liveliness(self, key: str, alive: bool) -> None:
        with self.network.lock:
            entries = self.network._live(self.network.liveliness_subscribers)
        for entry in entries:
            if key_matches(entry.expr, key):
                entry.handler(key, alive)  # type: ignore[operator]

    def serve(self, keyexpr: str, handler: QueryHandler) -> _Entry:
        """Answer queries matching ``keyexpr``."""
        entry = _Entry(self, validate_key(keyexpr, allow_wildcards=True), handler)
        with self.network.lock:
            self.network.queryables.append(entry)
        return entry

    def query(
        self, selector: str, payload: bytes | None = None, timeout_s: float = 1.0
    ) -> list[Sample]:
        """Ask every queryable whose expression intersects ``selector``."""
        validate_key(selector, allow_wildcards=True)
        with self.network.lock:
            entries = self.network._live(self.network.queryables)
        replies = []
        for entry in entries:
            # A concrete selector must fall in the queryable's expression (or vice versa).
            if key_matches(entry.expr, selector) or key_matches(selector, entry.expr):
                key = selector if "*" not in selector else entry.expr
                reply = entry.handler(key, payload)  # type: ignore[operator]
                if reply is not None:
                    replies.append(Sample(key, bytes(reply)))
        return replies

    def close(self) -> None:
        """Close the bus: its tokens vanish and its subscriptions stop."""
        if self.closed:
            return
        with self.network.lock:
            mine = [(i, key) for i, (bus, key) in self.network.tokens.items() if bus is self]
            for i, _ in mine:
                del self.network.tokens[i]
        self.closed = True
        for _, key in mine:
            self._notify_liveliness(key, False)
