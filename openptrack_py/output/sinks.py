"""Sinks: where output frames go, each isolated from the others.

A :class:`Sink` turns frames into bytes for one destination. A :class:`SinkWorker` runs
one sink on its own thread behind a small queue that drops the oldest frame when the
sink falls behind, so an absent, unreachable or slow receiver never delays the smoother
or the other sinks: the producer's :meth:`SinkWorker.submit` never blocks.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections import deque
from typing import Protocol

from openptrack_py.config import UdpSinkConfig
from openptrack_py.messages.track import TrackBatch
from openptrack_py.output.opt_json import encode_opt_heartbeats, encode_tracks
from openptrack_py.runtime.counters import Counters
from openptrack_py.runtime.logs import RateLimitedLog

log = logging.getLogger(__name__)


class Sink(Protocol):
    """One destination of output frames."""

    name: str
    poll_interval_s: float | None
    """How often :meth:`poll` must run even without frames (``None``: never)."""

    def send(self, frame: TrackBatch, now: float) -> None:
        """Deliver one frame (runs on the sink's own thread)."""

    def poll(self, now: float) -> None:
        """Periodic duties, e.g. heartbeats (runs on the sink's own thread)."""

    def close(self) -> None:
        """Release sockets."""


class SinkWorker:
    """Runs one sink on its own thread.

    Parameters
    ----------
    sink : Sink
        The sink.
    counters : Counters
        Where ``<name>.sent``, ``<name>.errors`` and ``<name>.dropped`` are counted.
    queue_size : int
        Frames that may wait; older ones are dropped first.
    """

    def __init__(self, sink: Sink, counters: Counters, queue_size: int = 4) -> None:
        self.sink = sink
        self.counters = counters
        self._queue: deque[TrackBatch] = deque(maxlen=queue_size)
        self._cond = threading.Condition()
        self._closed = False
        self._errors = RateLimitedLog(log, interval_s=10.0)
        self._thread = threading.Thread(target=self._run, name=f"sink-{sink.name}", daemon=True)
        self._thread.start()

    def submit(self, frame: TrackBatch) -> None:
        """Queue a frame for the sink; never blocks."""
        with self._cond:
            if len(self._queue) == self._queue.maxlen:
                self.counters.inc(f"{self.sink.name}.dropped")
            self._queue.append(frame)
            self._cond.notify()

    def _run(self) -> None:
        interval = self.sink.poll_interval_s
        while True:
            with self._cond:
                if not self._queue and not self._closed:
                    self._cond.wait(timeout=interval)
                if self._closed and not self._queue:
                    break
                frame = self._queue.popleft() if self._queue else None
            now = time.time()
            try:
                if frame is not None:
                    self.sink.send(frame, now)
                    self.counters.inc(f"{self.sink.name}.sent")
                self.sink.poll(now)
            except OSError as exc:  # unreachable, refused, no route...: count and go on
                self.counters.inc(f"{self.sink.name}.errors")
                self._errors.warning(self.sink.name, "sink error", sink=self.sink.name, error=exc)
            except Exception:
                self.counters.inc(f"{self.sink.name}.errors")
                log.exception("sink %s failed", self.sink.name)
        self.sink.close()  # on this thread: nothing can use the sink after it is closed

    def close(self, timeout_s: float = 2.0) -> None:
        """Send what is queued, then stop.

        A sink stuck longer than ``timeout_s`` is abandoned: its queue is emptied and it
        closes itself when its send returns.
        """
        with self._cond:
            self._closed = True
            self._cond.notify()
        self._thread.join(timeout_s)
        if self._thread.is_alive():
            with self._cond:
                self._queue.clear()
            log.warning("sink %s did not stop within %g s", self.sink.name, timeout_s)


class _Resolver:
    """Resolves a host name once, on the sink's thread.

    After a failure it retries only every ``retry_s``: a dead name server must not be
    asked on every frame.
    """

    def __init__(self, host: str, port: int, retry_s: float = 5.0) -> None:
        self.host, self.port, self.retry_s = host, port, retry_s
        self._address: tuple[str, int] | None = None
        self._retry_at = 0.0
        self._error: OSError | None = None

    def address(self) -> tuple[str, int]:
        """The resolved ``(ip, port)``; raises the last lookup error while it fails."""
        if self._address is not None:
            return self._address
        now = time.monotonic()
        if now < self._retry_at and self._error is not None:
            raise self._error
        try:
            self._address = (socket.gethostbyname(self.host), self.port)
        except OSError as exc:
            self._error = OSError(f"cannot resolve {self.host!r}: {exc}")
            self._retry_at = now + self.retry_s
            raise self._error from None
        return self._address


class UdpJsonSink:
    """OpenPTrack-compatible JSON over UDP to one destination.

    Parameters
    ----------
    cfg : UdpSinkConfig
        Destination and format.
    name : str
        Name used in counters and logs.
    """

    def __init__(self, cfg: UdpSinkConfig, name: str = "udp") -> None:
        self.cfg = cfg
        self.name = name
        self.poll_interval_s = cfg.heartbeat_interval_s if cfg.heartbeat else None
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        if cfg.mode == "broadcast":
            self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
        elif cfg.mode == "multicast":
            self._sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, cfg.ttl)
            self._sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
        self._sock.setblocking(False)  # a full buffer drops a datagram, never waits
        self._resolver = _Resolver(cfg.host, cfg.port)
        self._heartbeat_seq = 0
        self._alive: tuple[int, ...] = ()
        self._max_id = 0
        self._next_heartbeat = 0.0

    def _send(self, data: bytes) -> None:
        try:
            self._sock.sendto(data, self._resolver.address())
        except BlockingIOError:
            raise OSError("socket buffer full, datagram dropped") from None

    def send(self, frame: TrackBatch, now: float) -> None:
        """Send one tracks frame (one datagram unless it exceeds the size limit)."""
        self._alive, self._max_id = frame.alive_ids, frame.max_id
        for data in encode_tracks(
            frame.tracks,
            seq=frame.seq,
            stamp=frame.stamp,
            fmt=self.cfg.format,
            trailing_nul=self.cfg.trailing_nul,
            max_bytes=self.cfg.max_datagram_bytes,
            frame_id=frame.frame_id,
        ):
            self._send(data)

    def poll(self, now: float) -> None:
        """Send a heartbeat when one is due (also while the room is empty)."""
        if not self.cfg.heartbeat or now < self._next_heartbeat:
            return
        self._next_heartbeat = now + self.cfg.heartbeat_interval_s
        self._heartbeat_seq += 1
        for data in encode_opt_heartbeats(
            self._alive,
            self._max_id,
            seq=self._heartbeat_seq,
            stamp=now,
            trailing_nul=self.cfg.trailing_nul,
            max_bytes=self.cfg.max_datagram_bytes,
        ):
            self._send(data)

    def close(self) -> None:
        """Close the socket."""
        self._sock.close()
