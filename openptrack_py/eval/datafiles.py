"""Rows of the data files that evaluations read: CSV, JSON lines, recordings.

A file's format is chosen by its extension: ``.csv`` (a header row naming the columns,
then one row per line; blank lines and lines starting with ``#`` are skipped) or
``.jsonl`` / ``.json`` / ``.ndjson`` (one JSON object per line, keys as the CSV columns,
``null`` or a missing key for an empty cell). A JSON-lines file whose first line has
the recorder's keys (``{"t": ..., "key": ..., "msg": ...}``, as ``openptrack node record``
writes) is a recording: its lines come out as :class:`Recorded` messages instead.

Files are streamed line by line. Each cell is checked when it is read (:class:`Row`),
and every problem is an :class:`ExternalFileError` naming the file, the line and the
column. Times are seconds with any origin: :meth:`Row.time` shifts them by
:data:`TIME_BASE_S` so that they are valid UNIX stamps for the messages built from them.
"""

from __future__ import annotations

import csv
import math
import re
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from itertools import chain
from pathlib import Path
from typing import Any

import orjson

from openptrack_py.errors import ConfigError, WireFormatError
from openptrack_py.messages.fields import MAX_NAME_LEN, NAME_RE
from openptrack_py.recordings import read_recording
from openptrack_py.recordings.files import MCAP_SUFFIX

TIME_BASE_S = 1.0e9
"""Added to every file time, so that times from any origin are valid UNIX stamps."""
TIME_RANGE_S = (-1.0e8, 1.0e10)
"""Accepted file times, seconds (a time in milliseconds is out of range)."""

CSV_SUFFIXES = (".csv",)
JSON_LINES_SUFFIXES = (".jsonl", ".json", ".ndjson")
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
class Row:
    """One record of a file: its cells by column (text for CSV, JSON values otherwise)."""

    path: Path
    line: int
    cells: dict[str, Any]

    def error(self, column: str | None, message: str) -> ExternalFileError:
        """The error for ``column`` of this row (for the caller to raise)."""
        return ExternalFileError(self.path, self.line, column, message)

    def has(self, column: str) -> bool:
        """Whether the cell of ``column`` is filled."""
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
    if suffix not in CSV_SUFFIXES + JSON_LINES_SUFFIXES + (MCAP_SUFFIX,):
        allowed = ", ".join(CSV_SUFFIXES + JSON_LINES_SUFFIXES + (MCAP_SUFFIX,))
        raise ExternalFileError(
            path, None, None, f"unknown format {suffix!r} (allowed: {allowed})"
        )
    return suffix


def _open(path: Path, mode: str) -> Any:
    try:
        return path.open(mode, **({"newline": "", "encoding": "utf-8-sig"} if mode == "r" else {}))
    except OSError as exc:
        raise ExternalFileError(path, None, None, f"cannot open ({exc.strerror})") from None


def _csv_rows(path: Path, columns: tuple[str, ...], required: tuple[str, ...]) -> Iterator[Row]:
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
                yield Row(path, line, values)
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


def read_records(path: Path, columns: tuple[str, ...], required: tuple[str, ...]) -> Records:
    """The records of a file: rows (CSV or JSON lines) or a recording (MCAP or lines)."""
    if _suffix(path) in CSV_SUFFIXES:
        return Records(rows=_csv_rows(path, columns, required))
    if _suffix(path) == MCAP_SUFFIX:
        return Records(recording=_mcap_recording(path))
    lines = _json_lines(path)
    first = next(lines, None)
    if first is None:
        raise ExternalFileError(path, None, None, "empty")
    if first[1].keys() >= _RECORDING_KEYS:
        return Records(recording=_recording(path, chain([first], lines)))
    return Records(rows=_json_rows(path, chain([first], lines), columns))


@dataclass
class Records:
    """What a file holds: rows (CSV or JSON lines), or a recording's messages."""

    rows: Iterator[Row] | None = None
    recording: Iterator[Recorded] | None = None


def _json_rows(
    path: Path, lines: Iterator[tuple[int, dict]], columns: tuple[str, ...]
) -> Iterator[Row]:
    """Rows of JSON objects (a missing key or ``null`` is an empty cell)."""
    for line, obj in lines:
        for key in obj:
            if key not in columns:
                raise ExternalFileError(
                    path, line, key, f"unknown key (allowed: {', '.join(columns)})"
                )
        yield Row(path, line, {k: v for k, v in obj.items() if v is not None and v != ""})


@dataclass(frozen=True, slots=True)
class Recorded:
    """One line of a recording: receive time, topic, message (as its JSON bytes)."""

    path: Path
    line: int
    received: float
    topic: str
    payload: bytes

    def stamp(self, stamp: float) -> float:
        """A stamp of the message, checked and shifted like every file time."""
        return Row(self.path, self.line, {"msg.stamp": stamp}).time("msg.stamp")

    def decode(self, decoder: Callable[[bytes], Any]) -> Any:
        """The message, decoded and validated by ``decoder``.

        Raises
        ------
        ExternalFileError
            Naming the line and the message's field that is wrong.
        """
        try:
            return decoder(self.payload)
        except WireFormatError as exc:
            raise ExternalFileError(self.path, self.line, "msg", str(exc)) from None


def _recording(path: Path, lines: Iterator[tuple[int, dict]]) -> Iterator[Recorded]:
    for line, obj in lines:
        if not obj.keys() >= _RECORDING_KEYS:
            raise ExternalFileError(
                path, line, None, 'expected a recorder line {"t", "key", "msg"}'
            )
        key, received = obj["key"], obj["t"]
        if type(key) is not str:
            raise ExternalFileError(path, line, "key", f"expected a string, got {key!r}")
        row = Row(path, line, {"t": received})
        chunks = key.split("/")
        topic = "/".join(chunks[2:]) if len(chunks) >= 3 and chunks[0] == "opt" else ""
        yield Recorded(path, line, row.time("t"), topic, orjson.dumps(obj["msg"]))


def _mcap_recording(path: Path) -> Iterator[Recorded]:
    """An MCAP recording's messages (up to any damage, which is reported as a warning)."""
    recording = read_recording(path)
    for message in recording:
        row = Row(path, message.index, {"t": message.received})
        yield Recorded(path, message.index, row.time("t"), message.topic, message.payload)
    if recording.stopped:
        warnings.warn(recording.stopped, stacklevel=2)


def check_order(row: Row, previous: float | None, now: float, what: str, rule: str) -> None:
    """Raise unless ``now`` comes after ``previous`` (the time of the previous ``what``)."""
    if previous is not None and now <= previous:
        raise row.error(
            "time",
            f"{what} at {now - TIME_BASE_S:g} s does not come after the previous one at "
            f"{previous - TIME_BASE_S:g} s ({rule})",
        )
