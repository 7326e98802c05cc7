"""Ground truth, detections and tracks read from files, to score trackers on anyone's data.

``openptrack eval --ground-truth GT --detections DETS`` runs our tracker on detections
that did not come from our simulator; ``--tracks TRACKS`` scores another tracker's
output on the same ground truth. Files are ``.csv`` with a header row or JSON lines with
the same keys (:mod:`~openptrack_py.eval.datafiles` reads them); times are seconds with
any origin, the same clock in every file of one evaluation.

Ground truth: ``time, id, x, y[, covered]``
    Rows of one time are one frame: everyone present then (``id`` an integer, ``x, y``
    metres on the floor). ``covered`` (0/1, default 1) says whether a sensor could see
    the person; uncovered people are "don't care". A row with an empty ``id`` (and no
    ``x, y``) is a frame with nobody in it.
Detections: ``time, sensor[, x, y, confidence, z, height, distance, arrival, frame]``
    Rows of one ``(time, sensor)`` are one sensor frame (one DetectionBatch); a row
    without ``x, y`` is a frame in which that sensor saw nobody (write those: they tell
    the tracker that time passes). Defaults for what a 2-D source does not know:
    ``confidence`` :data:`DEFAULT_CONFIDENCE`, ``height`` :data:`DEFAULT_HEIGHT_M`,
    ``z`` half the height (a standing person's centroid, as our detector reports it),
    ``distance`` from the sensor :data:`DEFAULT_DISTANCE_M` (it sets the measurement
    noise), ``arrival`` (when the frame reached the tracker) ``time`` plus the
    evaluation's latency, ``frame`` ``world`` (or the sensor's name: its floor frame).
Tracks: ``time, id, x, y[, vx, vy]``
    Rows of one time are one output of the tracker: every track it reported then (a
    row with an empty ``id`` is an output with no track). Velocities (default 0) move
    the output to the ground-truth times in between.
Recordings
    A JSON-lines file written by the recorder (``openptrack node record``: lines
    ``{"t": ..., "key": ..., "msg": ...}``) is accepted as each of the three: its
    ``ground_truth`` messages, its ``detections/<sensor>`` messages (arriving at ``t``)
    and its raw ``tracks`` messages.

Rows come in time order: ground-truth and track frames increasing, detection frames in
order of arrival (a step back of up to :data:`MAX_DISORDER_S` is taken as arriving with
the previous frame), each sensor's times increasing. Files are streamed; every error is
an :class:`ExternalFileError` naming the file, the line and the column.
"""

from __future__ import annotations

import heapq
import math
import time
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from openptrack_py.errors import WireFormatError
from openptrack_py.eval.datafiles import (
    TIME_BASE_S,
    ExternalFileError,
    Recorded,
    Row,
    check_order,
    read_records,
)
from openptrack_py.eval.metrics import MotAccumulator
from openptrack_py.eval.runner import (
    EvalResult,
    Event,
    Hypotheses,
    HypothesisFeed,
    SensorsEnded,
    play,
    tracker_ms_per_batch,
)
from openptrack_py.messages.codec import (
    decode_detection_batch,
    decode_ground_truth,
    decode_track_batch,
)
from openptrack_py.messages.detection import Detection, DetectionBatch
from openptrack_py.messages.fields import MAX_ITEMS
from openptrack_py.messages.ground_truth import GroundTruthFrame, PersonState
from openptrack_py.sim.simulator import SensorFrame, TruthFrame

__all__ = [
    "DEFAULT_CONFIDENCE",
    "DEFAULT_DISTANCE_M",
    "DEFAULT_HEIGHT_M",
    "MAX_DISORDER_S",
    "ExternalFileError",
    "TrackFileFeed",
    "TrackFrame",
    "evaluate_files",
    "read_detections",
    "read_ground_truth",
    "read_tracks",
]

DEFAULT_CONFIDENCE = 1.0
"""Confidence of a detection whose file gives none."""
DEFAULT_HEIGHT_M = 1.7
"""Height of a detected person whose file gives none, metres (an adult)."""
DEFAULT_DISTANCE_M = 3.0
"""Distance from the sensor of a detection whose file gives none, metres."""
MAX_DISORDER_S = 1.0
"""Largest step back in arrival time between two detection frames, seconds."""

GROUND_TRUTH_COLUMNS = ("time", "id", "x", "y", "covered")
DETECTION_COLUMNS = (
    "time", "sensor", "x", "y", "confidence", "z", "height", "distance", "arrival", "frame"
)  # fmt: skip
TRACK_COLUMNS = ("time", "id", "x", "y", "vx", "vy")

_FRAMES_RULE = "rows of one time must be consecutive, times increasing"


# --------------------------------------------------------------------- ground truth


def read_ground_truth(path: Path) -> Iterator[TruthFrame]:
    """Stream the ground-truth frames of a file (see the module for its formats).

    Yields
    ------
    TruthFrame
        One frame per time, with times shifted by :data:`TIME_BASE_S`.

    Raises
    ------
    ExternalFileError
        Naming the file, line and column of the first problem.
    """
    path = Path(path)
    records = read_records(path, GROUND_TRUTH_COLUMNS, ("time", "id", "x", "y"))
    if records.rows is not None:
        frames = _truth_from_rows(records.rows)
    else:
        frames = _truth_from(records.recording)
    count = 0
    for frame in frames:
        count += 1
        yield frame
    if not count:
        raise ExternalFileError(path, None, None, "no ground-truth frame in the file")


def _truth_from_rows(rows: Iterator[Row]) -> Iterator[TruthFrame]:
    seq = 0
    stamp: float | None = None
    people: dict[int, PersonState] = {}
    for row in rows:
        t = row.time()
        if t != stamp:
            if stamp is not None:
                yield _truth_frame(stamp, seq, people)
                seq += 1
            check_order(row, stamp, t, "frame", _FRAMES_RULE)
            stamp, people = t, {}
        if row.nobody(("id", "x", "y")):
            continue
        pid = row.integer("id")
        if pid in people:
            raise row.error("id", f"person {pid} appears twice at time {t - TIME_BASE_S:g}")
        x, y = row.number("x"), row.number("y")
        people[pid] = PersonState(
            id=pid, x=x, y=y, height=DEFAULT_HEIGHT_M, vx=0.0, vy=0.0,
            covered=row.flag("covered", True),
        )  # fmt: skip
    if stamp is not None:
        yield _truth_frame(stamp, seq, people)


def _truth_frame(stamp: float, seq: int, people: dict[int, PersonState]) -> TruthFrame:
    return TruthFrame(stamp, GroundTruthFrame(stamp=stamp, seq=seq, people=tuple(people.values())))


def _truth_from(recording: Iterator[Recorded] | None) -> Iterator[TruthFrame]:
    previous: float | None = None
    for item in recording or ():
        if item.topic != "ground_truth":
            continue
        frame: GroundTruthFrame = item.decode(decode_ground_truth)
        stamp = item.stamp(frame.stamp)
        if previous is not None and stamp <= previous:
            raise ExternalFileError(item.path, item.line, "msg.stamp", "not after the previous")
        previous = stamp
        yield TruthFrame(stamp, replace(frame, stamp=stamp))


# ----------------------------------------------------------------------- detections


def read_detections(path: Path, latency_s: float = 0.0) -> Iterator[SensorFrame]:
    """Stream the sensor frames of a detections file (see the module for its formats).

    Parameters
    ----------
    path : Path
        The file.
    latency_s : float
        Added to a frame's time to make its arrival when the file gives none.

    Yields
    ------
    SensorFrame
        One per ``(time, sensor)`` in order of arrival, times shifted by
        :data:`TIME_BASE_S`.

    Raises
    ------
    ExternalFileError
        Naming the file, line and column of the first problem.
    """
    path = Path(path)
    records = read_records(path, DETECTION_COLUMNS, ("time", "sensor"))
    if records.rows is not None:
        frames = _frames_from_rows(records.rows, latency_s)
    else:
        frames = _frames_from(records.recording)
    last_arrival = -math.inf
    for row, frame in frames:
        if frame.time < last_arrival - MAX_DISORDER_S:
            column = next(c for c in ("arrival", "t", "time") if row.has(c) or c == "time")
            raise row.error(
                column,
                f"frame arrives {last_arrival - frame.time:.3f} s before the previous one "
                "(rows must be in order of arrival: sort them by time)",
            )
        if frame.time < last_arrival:
            frame = replace(frame, time=last_arrival)
        last_arrival = frame.time
        yield frame


def _frames_from_rows(rows: Iterator[Row], latency_s: float) -> Iterator[tuple[Row, SensorFrame]]:
    seqs: dict[str, int] = {}
    last: dict[str, float] = {}
    key: tuple[float, str] | None = None
    first: Row | None = None
    arrival = 0.0
    detections: list[Detection] = []
    for row in rows:
        t, sensor = row.time(), row.name("sensor")
        if (t, sensor) != key:
            if key is not None and first is not None:
                yield first, _sensor_frame(first, key, arrival, detections, seqs)
            check_order(
                row,
                last.get(sensor),
                t,
                f"frame of sensor {sensor!r}",
                "rows of one (time, sensor) must be consecutive, each sensor's times increasing",
            )
            key, first, detections = (t, sensor), row, []
            last[sensor] = t
            arrival = row.time("arrival") if row.has("arrival") else t + latency_s
        elif row.has("arrival") and row.time("arrival") != arrival:
            raise row.error("arrival", "differs between rows of one frame")
        if not row.nobody(("x", "y")):
            detections.append(_detection(row))
            if len(detections) > MAX_ITEMS:
                raise row.error(None, f"more than {MAX_ITEMS} detections in one frame")
    if key is not None and first is not None:
        yield first, _sensor_frame(first, key, arrival, detections, seqs)


def _detection(row: Row) -> Detection:
    height = row.number("height", DEFAULT_HEIGHT_M)
    values = {
        "x": row.number("x"),
        "y": row.number("y"),
        "z": row.number("z", height / 2.0),
        "height": height,
        "confidence": row.number("confidence", DEFAULT_CONFIDENCE),
        "distance": row.number("distance", DEFAULT_DISTANCE_M),
    }
    try:
        return Detection(**values)
    except WireFormatError as exc:  # a value out of range: name the column
        message = str(exc).removeprefix("Detection.")
        column, _, what = message.partition(": ")
        raise row.error(column, what) from None


def _sensor_frame(
    row: Row,
    key: tuple[float, str],
    arrival: float,
    detections: list[Detection],
    seqs: dict[str, int],
) -> SensorFrame:
    stamp, sensor = key
    seq = seqs.get(sensor, -1) + 1
    seqs[sensor] = seq
    frame = row.name("frame") if row.has("frame") else "world"
    batch = DetectionBatch(sensor, seq, stamp, frame, tuple(detections))
    return SensorFrame(arrival, stamp, batch, ())


def _frames_from(recording: Iterator[Recorded] | None) -> Iterator[tuple[Row, SensorFrame]]:
    for item in recording or ():
        if item.topic.split("/")[0] != "detections":
            continue
        batch: DetectionBatch = item.decode(decode_detection_batch)
        stamp = item.stamp(batch.stamp)
        frame = SensorFrame(item.received, stamp, replace(batch, stamp=stamp), ())
        yield Row(item.path, item.line, {"t": item.received}), frame


# --------------------------------------------------------------------------- tracks


@dataclass(frozen=True, slots=True)
class TrackFrame:
    """One output of a tracker read from a file.

    Parameters
    ----------
    time : float
        When the output holds, seconds (shifted by :data:`TIME_BASE_S`).
    ids : ndarray of int64
        Track ids.
    xy : ndarray
        ``(n, 2)`` positions, metres.
    vxy : ndarray
        ``(n, 2)`` velocities, metres per second.
    """

    time: float
    ids: np.ndarray
    xy: np.ndarray
    vxy: np.ndarray


def read_tracks(path: Path) -> Iterator[TrackFrame]:
    """Stream a tracker's outputs from a file (see the module for its formats).

    Raises
    ------
    ExternalFileError
        Naming the file, line and column of the first problem.
    """
    path = Path(path)
    records = read_records(path, TRACK_COLUMNS, ("time", "id", "x", "y"))
    if records.rows is not None:
        yield from _tracks_from_rows(records.rows)
    else:
        yield from _tracks_from(records.recording)


def _tracks_from_rows(rows: Iterator[Row]) -> Iterator[TrackFrame]:
    stamp: float | None = None
    tracks: dict[int, tuple[float, float, float, float]] = {}
    for row in rows:
        t = row.time()
        if t != stamp:
            if stamp is not None:
                yield _track_frame(stamp, tracks)
            check_order(row, stamp, t, "output", _FRAMES_RULE)
            stamp, tracks = t, {}
        if row.nobody(("id", "x", "y")):
            continue
        tid = row.integer("id")
        if tid in tracks:
            raise row.error("id", f"track {tid} appears twice at time {t - TIME_BASE_S:g}")
        tracks[tid] = (
            row.number("x"),
            row.number("y"),
            row.number("vx", 0.0),
            row.number("vy", 0.0),
        )
    if stamp is not None:
        yield _track_frame(stamp, tracks)


def _track_frame(stamp: float, tracks: dict[int, tuple[float, float, float, float]]) -> TrackFrame:
    values = np.array(list(tracks.values()), dtype=np.float64).reshape(-1, 4)
    return TrackFrame(stamp, np.array(list(tracks), dtype=np.int64), values[:, :2], values[:, 2:])


def _tracks_from(recording: Iterator[Recorded] | None) -> Iterator[TrackFrame]:
    previous: float | None = None
    for item in recording or ():
        if item.topic != "tracks":  # raw tracker output, not tracks/smoothed
            continue
        batch = item.decode(decode_track_batch)
        stamp = item.stamp(batch.stamp)
        if previous is not None and stamp < previous:
            continue  # a late batch replayed by the tracker: its newer output is known
        previous = stamp
        tracks = {t.id: (t.x, t.y, t.vx, t.vy) for t in batch.tracks}
        yield _track_frame(stamp, tracks)


@dataclass
class TrackFileFeed:
    """Hypotheses from a tracker's recorded output (see :func:`read_tracks`).

    At a ground-truth time the latest output not later than it is moved along each
    track's velocity; output older than ``stale_after_s`` counts as no output (as for
    :class:`~openptrack_py.eval.runner.TrackerFeed`).

    Parameters
    ----------
    frames : iterator of TrackFrame
        The outputs, in time order.
    stale_after_s : float
        Output older than this counts as no output at all.
    """

    frames: Iterator[TrackFrame]
    stale_after_s: float = 1.0
    _latest: TrackFrame | None = None
    _next: TrackFrame | None = None

    def __post_init__(self) -> None:
        self._next = next(self.frames, None)  # the first output (the file opens now)

    @classmethod
    def from_file(cls, path: Path, stale_after_s: float = 1.0) -> TrackFileFeed:
        """A feed reading ``path`` as it goes."""
        return cls(read_tracks(path), stale_after_s)

    def on_sensor_frame(self, frame: SensorFrame) -> None:
        """Sensors are not used: the tracks are already there."""

    def on_truth_frame(self, frame: TruthFrame) -> None:
        """The ground truth is not looked at."""

    def hypotheses_at(self, t: float) -> Hypotheses | None:
        """The latest output at or before ``t``, moved to ``t``."""
        while self._next is not None and self._next.time <= t:
            self._latest, self._next = self._next, next(self.frames, None)
        latest = self._latest
        if latest is None or t - latest.time > self.stale_after_s:
            return None
        return Hypotheses(latest.ids, latest.xy + latest.vxy * (t - latest.time))


# ----------------------------------------------------------------------- evaluation


def evaluate_files(
    ground_truth: Path,
    feed: HypothesisFeed,
    *,
    detections: Path | None = None,
    latency_s: float = 0.0,
    max_distance_m: float = 0.5,
    warmup_s: float = 0.0,
) -> EvalResult:
    """Score ``feed`` against a ground-truth file, fed by a detections file if given.

    Frames are scored exactly as for a simulated scenario
    (:func:`~openptrack_py.eval.runner.play`): each ground-truth frame is scored
    against the feed's hypotheses at its time; detection frames reach the feed in
    order of arrival, and after the last one the feed may apply what it still holds.

    Parameters
    ----------
    ground_truth : Path
        Ground-truth file.
    feed : HypothesisFeed
        A tracker feed (with ``detections``), a :class:`TrackFileFeed`, or the oracle.
    detections : Path, optional
        Detections file.
    latency_s : float
        Arrival delay of detection frames whose file gives no arrival, seconds.
    max_distance_m : float
        Largest distance at which a hypothesis may correspond to a person.
    warmup_s : float
        Ground-truth frames in the first ``warmup_s`` are not scored.

    Raises
    ------
    ExternalFileError
        For an unreadable or malformed file.
    """
    truth: Iterator[Event] = read_ground_truth(Path(ground_truth))
    events: Iterator[Event] = truth
    if detections is not None:
        frames = _ended(read_detections(Path(detections), latency_s))
        events = heapq.merge(frames, truth, key=lambda e: e.time)  # detections first on ties
    acc = MotAccumulator(max_distance_m)
    start = time.perf_counter()
    played = play(events, feed, acc, max_distance_m=max_distance_m, warmup_s=warmup_s)
    wall = time.perf_counter() - start
    first, last = played.first_truth or 0.0, played.last_truth or 0.0
    return EvalResult(
        metrics=acc.compute(),
        scenario=Path(ground_truth).name,
        seed=None,
        duration_s=round(last - first, 6),
        sensors=len(played.sensors),
        batches=played.batches,
        wall_s=wall,
        tracker_ms_per_batch=tracker_ms_per_batch(feed),
    )


def _ended(frames: Iterator[SensorFrame]) -> Iterator[SensorFrame | SensorsEnded]:
    last = -math.inf
    for frame in frames:
        last = frame.time
        yield frame
    yield SensorsEnded(last)
