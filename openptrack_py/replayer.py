"""Putting a recording back on the bus, at its original pace or faster.

:class:`Replayer` is the body of ``openptrack replay``: it streams a recording
(:func:`~openptrack_py.recordings.read_recording`) and puts each message of the chosen
topics on its key at the time it was received, scaled by ``speed``, so a demo, the
outputs and their clients run from a recording with no sensor at all. Messages are
re-stamped by default: every time in them (a batch's capture time, a tracks message's
stamps, a ground-truth frame's) follows the replay's clock, so the tracker takes them
as live (it refuses batches stamped far from their sensor's clock); faster than real
time, recorded time is compressed the same way. ``loop`` starts again at the end. The
keys keep their topic and take this network's site.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from openptrack_py.messages.codec import (
    decode_detection_batch,
    decode_ground_truth,
    decode_track_batch,
    encode_detection_batch,
    encode_ground_truth,
    encode_track_batch,
)
from openptrack_py.recordings import RecordedMessage, read_recording
from openptrack_py.recordings.files import MCAP_SUFFIX
from openptrack_py.runtime.node import Node

__all__ = ["DEFAULT_TOPICS", "ReplayProgress", "Replayer", "restamped"]

DEFAULT_TOPICS = ("detections",)
"""What is replayed unless told otherwise: the sensors' detections (a tracker takes them)."""


@dataclass(frozen=True)
class ReplayProgress:
    """Where a replay is.

    Parameters
    ----------
    recorded_s : float
        Recorded time replayed so far in this pass, seconds.
    total_s : float or None
        The recording's length, when its file says (MCAP statistics).
    messages : int
        Messages put so far.
    lap : int
        The pass (0 for the first).
    """

    recorded_s: float
    total_s: float | None
    messages: int
    lap: int


def restamped(message: RecordedMessage, clock: Callable[[float], float]) -> bytes:
    """``message``'s bytes with every time ``t`` in it made ``clock(t)``.

    Detections, tracks and ground truth carry times; other kinds go as they are.
    """
    kind = message.topic.split("/")[0]
    if kind == "detections":
        batch = decode_detection_batch(message.payload)
        return encode_detection_batch(replace(batch, stamp=clock(batch.stamp)))
    if kind == "tracks":
        tracks = decode_track_batch(message.payload)
        source = tracks.source
        if source is not None:
            source = (source[0], source[1], clock(source[2]))
        return encode_track_batch(replace(tracks, stamp=clock(tracks.stamp), source=source))
    if kind == "ground_truth":
        frame = decode_ground_truth(message.payload)
        return encode_ground_truth(replace(frame, stamp=clock(frame.stamp)))
    return message.payload


def recording_span(path: Path) -> tuple[float, float] | None:
    """``(first, last)`` receive time of an MCAP recording, from its statistics."""
    if path.suffix != MCAP_SUFFIX:
        return None
    try:
        from mcap.reader import make_reader

        with path.open("rb") as f:
            summary = make_reader(f).get_summary()
    except Exception:  # no summary (cut, or being written): the length is unknown
        return None
    if summary is None or summary.statistics is None or not summary.statistics.message_count:
        return None
    stats = summary.statistics
    return stats.message_start_time / 1e9, stats.message_end_time / 1e9


class Replayer:
    """Replays a recording on a node's bus.

    Parameters
    ----------
    node : Node
        The node whose bus, counters and stop flag to use.
    path : Path
        The recording (MCAP or JSON lines).
    speed : float
        Replay speed relative to the recording (2 = twice as fast).
    loop : bool
        Start again at the end, until the node stops.
    topics : sequence of str
        Topics to put (``detections``, ``tracks``, ``ground_truth``...).
    restamp : bool
        Move the messages' times with the replay's clock.
    on_progress : callable, optional
        Called about twice a second with a :class:`ReplayProgress`.
    """

    def __init__(
        self,
        node: Node,
        path: Path,
        *,
        speed: float = 1.0,
        loop: bool = False,
        topics: Sequence[str] = DEFAULT_TOPICS,
        restamp: bool = True,
        on_progress: Callable[[ReplayProgress], None] | None = None,
    ) -> None:
        if not speed > 0:
            raise ValueError(f"replay: speed must be > 0, got {speed}")
        self.node = node
        self.path = Path(path)
        self.speed = speed
        self.loop = loop
        self.topics = tuple(topics)
        self.restamp = restamp
        self.on_progress = on_progress
        self.stopped: str | None = None
        self._publishers: dict[str, object] = {}

    def _put(self, message: RecordedMessage, clock: Callable[[float], float]) -> None:
        key = self.node.keys.relative(message.topic)
        publisher = self._publishers.get(key)
        if publisher is None:
            publisher = self._publishers[key] = self.node.publisher(key)
        payload = restamped(message, clock) if self.restamp else message.payload
        publisher.put(payload)  # type: ignore[attr-defined]

    def run(self) -> int:
        """Replay until the end (or, looping, until the node stops); messages put."""
        span = recording_span(self.path)
        total = None if span is None else span[1] - span[0]
        put, lap, shown = 0, 0, 0.0
        start_wall = time.time()
        lap_offset = 0.0  # recorded seconds of the passes before this one
        while self.node.running:
            recording = read_recording(self.path)
            first = last = None
            for message in recording:
                if not self.node.running:
                    return put
                if first is None:
                    first = message.received
                    base = start_wall + lap_offset / self.speed

                    def clock(t: float, first: float = first, base: float = base) -> float:
                        return base + (t - first) / self.speed

                last = message.received
                if message.topic.split("/")[0] not in self.topics:
                    continue
                wait = clock(message.received) - time.time()
                if wait > 0 and self.node.wait(wait):
                    return put
                self._put(message, clock)  # counted as "out" by the node's publisher
                put += 1
                if self.on_progress is not None and time.monotonic() - shown >= 0.5:
                    shown = time.monotonic()
                    recorded_s = message.received - first
                    self.on_progress(ReplayProgress(recorded_s, total, put, lap))
            self.stopped = recording.stopped
            if not self.loop or first is None or last is None:
                break
            lap += 1
            lap_offset += (last - first) + 1.0 / 30.0
        return put
