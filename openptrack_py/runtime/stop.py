"""A stop request that a signal handler can make without taking a lock.

Python runs a signal handler in the main thread between two bytecodes, possibly while
that thread holds a lock: inside :meth:`threading.Event.wait`, for one, the event's
condition lock is held again for a moment after every wake-up. A handler that calls
``Event.set()`` (or logs, or prints under a lock) there waits for a lock its own thread
holds and never returns; a process asked to stop hangs instead (a thread polling an event
in a tight loop was caught there by 5 of 13,456 signals in one measurement).

:meth:`StopRequest.from_signal` therefore only stores the signal number (one attribute
assignment). The request is turned into an event, and announced, by whichever thread next
asks :meth:`StopRequest.is_set` or waits in :meth:`StopRequest.wait`, which wakes at least
every :data:`POLL_S` to look.
"""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from collections.abc import Callable, Iterator
from types import FrameType

POLL_S = 0.1
"""Longest time between a signal and a waiting thread noticing it, seconds."""


class StopRequest:
    """A stop flag set by a thread (:meth:`set`) or by a signal (:meth:`from_signal`).

    Parameters
    ----------
    on_signal : callable, optional
        Called once, outside the signal handler, with the signal's name when a signal
        asked to stop (to log or print it).
    """

    def __init__(self, on_signal: Callable[[str], None] | None = None) -> None:
        self._event = threading.Event()
        self._signum: int | None = None
        self._on_signal = on_signal
        self._announce = threading.Lock()
        self._announced = False

    def from_signal(self, signum: int, _frame: FrameType | None = None) -> None:
        """Record a stop asked by signal ``signum`` (a signal handler: takes no lock)."""
        self._signum = signum

    def install(self, *signums: int) -> None:
        """Make each of ``signums`` (default SIGINT and SIGTERM) request a stop."""
        for signum in signums or (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, self.from_signal)

    def set(self) -> None:
        """Request a stop (from any thread, never from a signal handler)."""
        self._event.set()

    def is_set(self) -> bool:
        """Whether a stop was requested, by a thread or a signal."""
        signum = self._signum
        if signum is not None and not self._announced:
            with self._announce:
                if not self._announced:
                    self._announced = True
                    self._event.set()
                    if self._on_signal is not None:
                        self._on_signal(signal.Signals(signum).name)
        return self._event.is_set()

    def wait(self, timeout: float | None = None) -> bool:
        """Sleep until a stop is requested or ``timeout`` passes; return :meth:`is_set`."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self.is_set():
            left = POLL_S if deadline is None else min(POLL_S, deadline - time.monotonic())
            if left <= 0:
                return False
            self._event.wait(left)
        return True


@contextlib.contextmanager
def stop_on_signals() -> Iterator[StopRequest]:
    """A :class:`StopRequest` that SIGINT and SIGTERM make while the block runs.

    For a command's polling loop (Ctrl-C ends it, as a ``KeyboardInterrupt`` would, but
    never inside a lock the loop holds). The previous handlers come back after the block.
    Outside the main thread no handler can be installed: the request is then only set
    by :meth:`StopRequest.set`.
    """
    stop = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return
    previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    stop.install(*previous)
    try:
        yield stop
    finally:
        for signum, handler in previous.items():
            if handler is not None:  # None: installed outside Python, cannot be put back
                signal.signal(signum, handler)
