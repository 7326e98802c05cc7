"""Ground truth, detections and tracks read from files, to score trackers on anyone's data.

``openptrack eval --ground-truth GT --detections DETS`` runs our tracker on detections
that did not come from our simulator; ``--tracks TRACKS`` scores another tracker's
output on the same ground truth. The format is chosen by the extension: ``.csv`` (a
header row naming the columns, then one row per line; blank lines and lines starting
with ``#`` are skipped) or ``.jsonl`` / ``.json`` / ``.ndjson`` (one JSON object per
line with the same keys). Times are seconds with any origin, the same clock in every
file of one evaluation.

Ground truth: ``time, id, x, y[, covered]``
    Rows of one time are one frame: everyone present then (``id`` an integer, ``x, y``
    metres on the floor). ``covered`` (0/1, default 1) says whether a sensor could see
    the person; uncovered people are "don't care". A row with an empty ``id`` (and no
    ``x, y``) is a frame with nobody in it.
Detections: ``time, sensor[, x, y, confidence, z, height, distance, arrival]``
    Rows of one ``(time, sensor)`` are one sensor frame (one DetectionBatch); a row
    without ``x, y`` is a frame in which that sensor saw nobody (write those: they tell
    the tracker that time passes). Defaults for what a 2-D source does not know:
    ``confidence`` :data:`DEFAULT_CONFIDENCE`, ``height`` :data:`DEFAULT_HEIGHT_M`,
    ``z`` half the height (a standing person's centroid, as our detector reports it),
    ``distance`` from the sensor :data:`DEFAULT_DISTANCE_M` (it sets the measurement
    noise), ``arrival`` (when the frame reached the tracker) ``time`` plus the
    evaluation's latency.
Tracks: ``time, id, x, y[, vx, vy]``
    Rows of one time are one output of the tracker: every track it reported then (a
    row with an empty ``id`` is an output with no track). Velocities (default 0) move
    the output to the ground-truth times in between.
Recordings
    A JSON-lines file written by the recorder (``openptrack node record``: lines
    ``{"t": ..., "key": ..., "msg": ...}``) is accepted as each of the three: its
    ``ground_truth`` messages, its ``detections/<sensor>`` messages (arriving at ``t``)
    and its raw ``tracks`` messages.

Rows must come in time order: ground-truth and track frames strictly increasing,
detection frames in order of arrival (steps back of up to :data:`MAX_DISORDER_S` are
taken as arriving with the previous frame) and each sensor's times increasing. Files
are streamed, never loaded whole. Every error is an :class:`ExternalFileError` naming
the file, the line and the column.
"""

from __future__ import annotations

import csv
import heapq
import math
import re
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from itertools import chain
from pathlib import Path
from typing import Any

import numpy as np
import orjson

from openptrack_py.errors import ConfigError, WireFormatError
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
from openptrack_py.messages.fields import MAX_ITEMS, MAX_NAME_LEN, NAME_RE
from openptrack_py.messages.ground_truth import GroundTruthFrame, PersonState
from openptrack_py.sim.simulator import SensorFrame, TruthFrame

DEFAULT_CONFIDENCE = 1.0
"""Confidence of a detection whose file gives none."""
DEFAULT_HEIGHT_M = 1.7
"""Height of a detected person whose file gives none, metres (an adult)."""
DEFAULT_DISTANCE_M = 3.0
"""Distance from the sensor of a detection whose file gives none, metres."""
MAX_DISORDER_S = 1.0
"""Largest step back in arrival time between two detection frames, seconds."""
TIME_BASE_S = 1.0e9
"""Added to every file time, so that times from any origin are valid UNIX stamps."""
TIME_RANGE_S = (-1.0e8, 1.0e10)
"""Accepted file times, seconds (a time in milliseconds is out of range)."""

CSV_SUFFIXES = (".csv",)
JSON_LINES_SUFFIXES = (".jsonl", ".json", ".ndjson")

GROUND_TRUTH_COLUMNS = ("time", "id", "x", "y", "covered")
DETECTION_COLUMNS = (
    "time",
    "sensor",
    "x",
    "y",
    "confidence",
    "z",
    "height",
    "distance",
    "arrival",
)
TRACK_COLUMNS = ("time", "id", "x", "y", "vx", "vy")

_INTEGER_RE = re.compile(r"[+-]?\d+")
_INT64 = (-(1 << 63), (1 << 63) - 1)
_RECORDING_KEYS = frozenset({"t", "key", "msg"})


class ExternalFileError(ConfigError):
    """A ground-truth, detection or track file cannot be read.

    The message is ``<path>:<line>: <column>: <what is wrong>`` (line and column when
    they are known).

    Parameters
    ----------
    path : Path
        The file.
    line : int or None
        1-based line number.
    column : str or None
        Column (or JSON key) at fault.
    message : str
        What is wrong.
    """

    def __init__(self, path: Path, line: int | None, column: str | None, message: str) -> None:
        self.path, self.line, self.column = path, line, column
        where = str(path) if line is None else f"{path}:{line}"
        super().__init__(f"{where}: {column}: {message}" if column else f"{where}: {message}")


# ----------------------------------------------------------------------------- rows


@dataclass(frozen=True, slots=True)
class _Row:
    """One record of a file: its cells by column (text for CSV, JSON values otherwise)."""

    path: Path
    line: int
    cells: dict[str, Any]

    def error(self, column: str | None, message: str) -> ExternalFileError:
        return ExternalFileError(self.path, self.line, column, message)

    def has(self, column: str) -> bool:
        return self.cells.get(column) is not None

    def number(self, column: str, default: float | None = None) -> float:
        """A finite number; ``default`` when the cell is empty (required if ``None``)."""
        value = self.cells.get(column)
        if value is None:
            if default is None:
                raise self.error(column, "missing (a number is required)")
            return default
        if isinstance(value, str):
            try:
                number = float(value)
            except ValueError:
                raise self.error(column, f"expected a number, got {value!r}") from None
        elif type(value) in (int, float):
            number = float(value)
        else:
            raise self.error(column, f"expected a number, got {value!r}")
        if not math.isfinite(number):
            raise self.error(column, f"expected a finite number, got {value!r}")
        return number

    def time(self, column: str = "time") -> float:
        """A time in seconds, shifted by :data:`TIME_BASE_S`."""
        value = self.number(column)
        lo, hi = TIME_RANGE_S
        if not lo <= value <= hi:
            raise self.error(column, f"expected seconds in [{lo:g}, {hi:g}], got {value!r}")
        return value + TIME_BASE_S

    def integer(self, column: str) -> int:
        """A required 64-bit integer."""
        value = self.cells.get(column)
        if isinstance(value, str) and _INTEGER_RE.fullmatch(value):
            value = int(value)
        if type(value) is not int or not _INT64[0] <= value <= _INT64[1]:
            raise self.error(column, f"expected an integer, got {value!r}")
        return value

    def name(self, column: str) -> str:
        """A required sensor name (``[A-Za-z0-9_.-]``, 1 to 128 characters)."""
        value = self.cells.get(column)
        if type(value) is int:
            value = str(value)
        if type(value) is not str or not 0 < len(value) <= MAX_NAME_LEN:
            raise self.error(
                column, f"expected a name of 1-{MAX_NAME_LEN} characters, got {value!r}"
            )
        if not NAME_RE.fullmatch(value):
            raise self.error(column, f"expected only the characters [A-Za-z0-9_.-], got {value!r}")
        return value

    def flag(self, column: str, default: bool) -> bool:
        """``0``/``1`` (or ``true``/``false``); ``default`` when empty."""
        value = self.cells.get(column)
        if value is None:
            return default
        if isinstance(value, str):
            value = {"0": False, "1": True, "false": False, "true": True}.get(value.lower(), value)
        elif type(value) is int and value in (0, 1):
            value = bool(value)
        if type(value) is not bool:
            raise self.error(column, f"expected 0 or 1, got {value!r}")
        return value

    def nobody(self, columns: tuple[str, ...]) -> bool:
        """Whether the row marks a frame with nobody (every one of ``columns`` empty).

        Raises
        ------
        ExternalFileError
            If some of the columns are filled and others not.
        """
        filled = [c for c in columns if self.has(c)]
        if filled and len(filled) < len(columns):
            missing = next(c for c in columns if not self.has(c))
            raise self.error(missing, f"missing (give all of {', '.join(columns)} or none)")
        return not filled


def _suffix(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in CSV_SUFFIXES + JSON_LINES_SUFFIXES:
        allowed = ", ".join(CSV_SUFFIXES + JSON_LINES_SUFFIXES)
        raise ExternalFileError(
            path, None, None, f"unknown format {suffix!r} (allowed: {allowed})"
        )
    return suffix


def _open(path: Path, mode: str) -> Any:
    try:
        return path.open(mode, **({"newline": "", "encoding": "utf-8-sig"} if mode == "r" else {}))
    except OSError as exc:
        raise ExternalFileError(path, None, None, f"cannot open ({exc.strerror})") from None


def _csv_rows(path: Path, columns: tuple[str, ...], required: tuple[str, ...]) -> Iterator[_Row]:
    """The rows of a CSV file with a header, as cells by column (empty cells left out)."""
    with _open(path, "r") as f:
        reader = csv.reader(f)
        header: list[str] | None = None
        try:
            for cells in reader:
                if not cells or not "".join(cells).strip() or cells[0].lstrip().startswith("#"):
                    continue
                line = reader.line_num
                if header is None:
                    header = _header(path, line, [c.strip() for c in cells], columns, required)
                    continue
                if len(cells) != len(header):
                    raise ExternalFileError(
                        path, line, None, f"expected {len(header)} cells, got {len(cells)}"
                    )
                values = {h: v.strip() for h, v in zip(header, cells, strict=True) if v.strip()}
                yield _Row(path, line, values)
        except (csv.Error, UnicodeDecodeError) as exc:
            raise ExternalFileError(
                path, reader.line_num + 1, None, f"unreadable ({exc})"
            ) from None
    if header is None:
        raise ExternalFileError(path, None, None, "empty (expected a header row)")


def _header(
    path: Path, line: int, names: list[str], columns: tuple[str, ...], required: tuple[str, ...]
) -> list[str]:
    for name in names:
        if name not in columns:
            raise ExternalFileError(
                path, line, name, f"unknown column (allowed: {', '.join(columns)})"
            )
        if names.count(name) > 1:
            raise ExternalFileError(path, line, name, "repeated column")
    for name in required:
        if name not in names:
            raise ExternalFileError(path, line, name, "missing column")
    return names


def _json_lines(path: Path) -> Iterator[tuple[int, dict]]:
    """``(line number, object)`` for every non-blank line of a JSON-lines file."""
    with _open(path, "rb") as f:
        for line_no, text in enumerate(f, 1):
            if not text.strip():
                continue
            try:
                obj = orjson.loads(text)
            except orjson.JSONDecodeError as exc:
                raise ExternalFileError(
                    path, line_no, None, f"not valid JSON ({exc}; expected one object per line)"
                ) from None
            if type(obj) is not dict:
                raise ExternalFileError(path, line_no, None, "expected a JSON object")
            yield line_no, obj


def _records(path: Path, columns: tuple[str, ...], required: tuple[str, ...]) -> _Records:
    """The records of a file: rows (CSV or JSON lines) or recorder lines."""
    if _suffix(path) in CSV_SUFFIXES:
        return _Records(rows=_csv_rows(path, columns, required))
    lines = _json_lines(path)
    first = next(lines, None)
    if first is None:
        raise ExternalFileError(path, None, None, "empty")
    if first[1].keys() >= _RECORDING_KEYS:
        return _Records(recording=_recording(path, chain([first], lines)))
    return _Records(rows=_json_rows(path, chain([first], lines), columns))


@dataclass
class _Records:
    rows: Iterator[_Row] | None = None
    recording: Iterator[_Recorded] | None = None


def _json_rows(
    path: Path, lines: Iterator[tuple[int, dict]], columns: tuple[str, ...]
) -> Iterator[_Row]:
    """Rows of JSON objects (a missing key or ``null`` is an empty cell)."""
    for line, obj in lines:
        for key in obj:
            if key not in columns:
                raise ExternalFileError(
                    path, line, key, f"unknown key (allowed: {', '.join(columns)})"
                )
        yield _Row(path, line, {k: v for k, v in obj.items() if v is not None and v != ""})


@dataclass(frozen=True, slots=True)
class _Recorded:
    """One line of a recording: receive time, topic, message (as its JSON bytes)."""

    path: Path
    line: int
    received: float
    topic: str
    payload: bytes

    def decode(self, decoder: Callable[[bytes], Any]) -> Any:
        try:
            return decoder(self.payload)
        except WireFormatError as exc:
            raise ExternalFileError(self.path, self.line, "msg", str(exc)) from None


def _recording(path: Path, lines: Iterator[tuple[int, dict]]) -> Iterator[_Recorded]:
    for line, obj in lines:
        if not obj.keys() >= _RECORDING_KEYS:
            raise ExternalFileError(
                path, line, None, 'expected a recorder line {"t", "key", "msg"}'
            )
        key, received = obj["key"], obj["t"]
        if type(key) is not str:
            raise ExternalFileError(path, line, "key", f"expected a string, got {key!r}")
        row = _Row(path, line, {"t": received})
        chunks = key.split("/")
        topic = "/".join(chunks[2:]) if len(chunks) >= 3 and chunks[0] == "opt" else ""
        yield _Recorded(path, line, row.time("t"), topic, orjson.dumps(obj["msg"]))


def _in_order(row: _Row, previous: float | None, now: float, what: str, rule: str) -> None:
    """Raise unless ``now`` comes after ``previous`` (the time of the previous ``what``)."""
    if previous is not None and now <= previous:
        raise row.error(
            "time",
            f"{what} at {now - TIME_BASE_S:g} s does not come after the previous one at "
            f"{previous - TIME_BASE_S:g} s ({rule})",
        )


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
    records = _records(path, GROUND_TRUTH_COLUMNS, ("time", "id", "x", "y"))
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


def _truth_from_rows(rows: Iterator[_Row]) -> Iterator[TruthFrame]:
    seq = 0
    stamp: float | None = None
    people: dict[int, PersonState] = {}
    for row in rows:
        t = row.time()
        if t != stamp:
            if stamp is not None:
                yield _truth_frame(stamp, seq, people)
                seq += 1
            _in_order(row, stamp, t, "frame", _FRAMES_RULE)
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


def _truth_from(recording: Iterator[_Recorded] | None) -> Iterator[TruthFrame]:
    previous: float | None = None
    for item in recording or ():
        if item.topic != "ground_truth":
            continue
        frame: GroundTruthFrame = item.decode(decode_ground_truth)
        stamp = _Row(item.path, item.line, {"stamp": frame.stamp}).time("stamp")
        if previous is not None and stamp <= previous:
            raise ExternalFileError(
                item.path, item.line, "msg.stamp", "ground truth does not come after the previous"
            )
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
    records = _records(path, DETECTION_COLUMNS, ("time", "sensor"))
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


def _frames_from_rows(
    rows: Iterator[_Row], latency_s: float
) -> Iterator[tuple[_Row, SensorFrame]]:
    seqs: dict[str, int] = {}
    last: dict[str, float] = {}
    key: tuple[float, str] | None = None
    first: _Row | None = None
    arrival = 0.0
    detections: list[Detection] = []
    for row in rows:
        t, sensor = row.time(), row.name("sensor")
        if (t, sensor) != key:
            if key is not None and first is not None:
                yield first, _sensor_frame(first, key, arrival, detections, seqs)
            _in_order(
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


def _detection(row: _Row) -> Detection:
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
    row: _Row,
    key: tuple[float, str],
    arrival: float,
    detections: list[Detection],
    seqs: dict[str, int],
) -> SensorFrame:
    stamp, sensor = key
    seq = seqs.get(sensor, -1) + 1
    seqs[sensor] = seq
    batch = DetectionBatch(sensor, seq, stamp, "world", tuple(detections))
    return SensorFrame(arrival, stamp, batch, ())


def _frames_from(recording: Iterator[_Recorded] | None) -> Iterator[tuple[_Row, SensorFrame]]:
    for item in recording or ():
        if item.topic.split("/")[0] != "detections":
            continue
        batch: DetectionBatch = item.decode(decode_detection_batch)
        row = _Row(item.path, item.line, {"stamp": batch.stamp})
        stamp = row.time("stamp")
        frame = SensorFrame(item.received, stamp, replace(batch, stamp=stamp), ())
        yield _Row(item.path, item.line, {"t": item.received}), frame


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
    records = _records(path, TRACK_COLUMNS, ("time", "id", "x", "y"))
    if records.rows is not None:
        yield from _tracks_from_rows(records.rows)
    else:
        yield from _tracks_from(records.recording)


def _tracks_from_rows(rows: Iterator[_Row]) -> Iterator[TrackFrame]:
    stamp: float | None = None
    tracks: dict[int, tuple[float, float, float, float]] = {}
    for row in rows:
        t = row.time()
        if t != stamp:
            if stamp is not None:
                yield _track_frame(stamp, tracks)
            _in_order(row, stamp, t, "output", _FRAMES_RULE)
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


def _tracks_from(recording: Iterator[_Recorded] | None) -> Iterator[TrackFrame]:
    previous: float | None = None
    for item in recording or ():
        if item.topic != "tracks":  # raw tracker output, not tracks/smoothed
            continue
        batch = item.decode(decode_track_batch)
        stamp = _Row(item.path, item.line, {"stamp": batch.stamp}).time("stamp")
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
    _started: bool = field(default=False, repr=False)

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
        if not self._started:
            self._next, self._started = next(self.frames, None), True
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
