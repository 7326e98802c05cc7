"""The message bus every node talks through.

A :class:`Bus` publishes bytes on keys, delivers bytes to subscribers of key
expressions, announces liveliness tokens and answers queries. :class:`ZenohBus` is the
real one; :class:`MemoryBus` is an in-process stand-in for unit tests and
faster-than-real-time runs. Callbacks may run on a transport thread: keep them short and
hand work to the node's own loop.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable


@dataclass(frozen=True, slots=True)
class Sample:
    """One received message.

    Parameters
    ----------
    key : str
        The concrete key it was published on.
    payload : bytes
        The message bytes.
    """

    key: str
    payload: bytes


SampleHandler = Callable[[Sample], None]
LivelinessHandler = Callable[[str, bool], None]
QueryHandler = Callable[[str, bytes | None], bytes | None]
"""Receives the query's key and optional payload; returns the reply, or ``None`` for none."""


@runtime_checkable
class Closable(Protocol):
    """Anything declared on a bus: close it to undeclare."""

    def close(self) -> None:
        """Undeclare; idempotent."""


@runtime_checkable
class Publisher(Protocol):
    """A declared publisher on one key."""

    key: str

    def put(self, payload: bytes) -> None:
        """Publish ``payload``."""

    def has_subscribers(self) -> bool:
        """Whether any subscriber currently matches this key."""

    def close(self) -> None:
        """Undeclare; idempotent."""


@runtime_checkable
class Bus(Protocol):
    """Publish/subscribe, liveliness and queries over one session."""

    def publisher(self, key: str, *, reliable: bool = True) -> Publisher:
        """Declare a publisher.

        ``reliable=True`` blocks rather than drops when the network is congested
        (tracks, ground truth); ``False`` drops and sends at once (latest-only data).
        """

    def put(self, key: str, payload: bytes, *, reliable: bool = True) -> None:
        """Publish once without declaring a publisher."""

    def subscribe(self, keyexpr: str, handler: SampleHandler) -> Closable:
        """Call ``handler`` for every sample whose key matches ``keyexpr``."""

    def declare_token(self, key: str) -> Closable:
        """Announce a liveliness token that lives until closed or the session ends.

        Keep the returned object: dropping it may undeclare the token.
        """

    def alive(self, keyexpr: str, timeout_s: float = 1.0) -> list[str]:
        """Keys of the liveliness tokens currently matching ``keyexpr``."""

    def subscribe_liveliness(self, keyexpr: str, handler: LivelinessHandler) -> Closable:
        """Call ``handler(key, alive)`` when a matching token appears or disappears.

        Tokens already present are reported first.
        """

    def serve(self, keyexpr: str, handler: QueryHandler) -> Closable:
        """Answer queries on ``keyexpr`` with ``handler``."""

    def query(
        self, selector: str, payload: bytes | None = None, timeout_s: float = 1.0
    ) -> list[Sample]:
        """Ask every matching queryable; return their replies."""

    def close(self) -> None:
        """Close the session and everything declared on it; idempotent."""


def wait_for_subscribers(publisher: Publisher, timeout_s: float = 10.0) -> bool:
    """Wait until ``publisher`` has a matching subscriber.

    Publishers that must not lose their first samples (tests, one-shot tools) wait here
    before putting; live nodes simply start publishing.

    Returns
    -------
    bool
        Whether a subscriber matched within ``timeout_s``.
    """
    deadline = time.monotonic() + timeout_s
    while not publisher.has_subscribers():
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.002)
    return True
