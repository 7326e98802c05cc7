"""Recording files: MCAP (the default) and JSON lines, written and read as streams.

A recording is the messages of a site as a node received them: for each, the receive
time, the key it came on and its bytes (the JSON of :mod:`openptrack_py.messages`).

* **MCAP** (``.mcap``), the format robotics tools such as Foxglove open directly: one
  channel per key (its topic, ``message_encoding: json``) with the JSON Schema of its
  kind (:mod:`~openptrack_py.recordings.schemas`), ``log_time`` the receive time, zstd
  chunks closed at least every ``flush_every_s`` (so a power cut loses at most that
  much, and a recording being written can be read up to its last closed chunk), and
  metadata records (``openptrack``: what recorded it, and the network file).
* **JSON lines** (``.jsonl``): ``{"t": <receive time>, "key": "<key>", "msg": <message>}``
  per line, as the recorder always wrote.

:func:`read_recording` streams either kind (never loading the file whole) and stops at
the first damage (a cut or corrupt record, a broken line): everything before it is
read, and :attr:`Recording.stopped` says where it stopped and why.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Protocol

import orjson

from openptrack_py.errors import ConfigError
from openptrack_py.recordings.schemas import schema_bytes, schema_for_key

__all__ = [
    "JsonLinesWriter",
    "McapWriter",
    "RecordedMessage",
    "Recording",
    "RecordingWriter",
    "open_writer",
    "read_recording",
]

MCAP_SUFFIX = ".mcap"
FLUSH_EVERY_S = 1.0
"""Longest time a received message waits in memory before it is in the file."""


@dataclass(frozen=True, slots=True)
class RecordedMessage:
    """One recorded message.

    Parameters
    ----------
    received : float
        When the recording node received it, UNIX seconds.
    key : str
        The key it came on (``opt/<site>/<topic>/...``).
    payload : bytes
        Its bytes, as sent.
    index : int
        Its place in the file (1 for the first message): line or MCAP message number.
    """

    received: float
    key: str
    payload: bytes
    index: int

    @property
    def topic(self) -> str:
        """The key below ``opt/<site>/`` (``detections/k2_a``, ``tracks``...)."""
        chunks = self.key.split("/")
        return "/".join(chunks[2:]) if len(chunks) >= 3 and chunks[0] == "opt" else ""

    @property
    def site(self) -> str:
        """The site of the key (``opt/<site>/...``)."""
        chunks = self.key.split("/")
        return chunks[1] if len(chunks) >= 2 else ""


class RecordingWriter(Protocol):
    """Appends received messages to a recording."""

    path: Path

    def write(self, received: float, key: str, payload: bytes) -> None:
        """Append one message."""

    def flush(self) -> None:
        """Put what was written so far in the file."""

    def flush_if_due(self) -> None:
        """Flush if what is held has waited its longest (call it when traffic pauses)."""

    def close(self) -> None:
        """Finish the file."""


class JsonLinesWriter:
    """A recording as JSON lines.

    Parameters
    ----------
    path : Path
        The file (appended to).
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._out: IO[bytes] = self.path.open("ab")

    def write(self, received: float, key: str, payload: bytes) -> None:
        """Append one message as a line."""
        self._out.write(b'{"t":' + orjson.dumps(received) + b',"key":' + orjson.dumps(key))
        self._out.write(b',"msg":' + payload + b"}\n")

    def flush(self) -> None:
        """Flush the file."""
        self._out.flush()

    def flush_if_due(self) -> None:
        """Flush the file (a line costs nothing to flush)."""
        self._out.flush()

    def close(self) -> None:
        """Close the file."""
        self._out.close()


class McapWriter:
    """A recording as MCAP.

    Parameters
    ----------
    path : Path
        The file (created; must not exist).
    metadata : mapping of str to mapping, optional
        Metadata records to write first (name -> string fields).
    flush_every_s : float
        Longest time between two chunks closed and written.
    """

    def __init__(
        self,
        path: Path,
        metadata: Mapping[str, Mapping[str, str]] | None = None,
        flush_every_s: float = FLUSH_EVERY_S,
    ) -> None:
        from mcap.writer import CompressionType, Writer

        self.path = Path(path)
        self._file = self.path.open("xb")
        self._writer = Writer(self._file, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library="openptrack_py")
        for name, data in (metadata or {}).items():
            self._writer.add_metadata(name, dict(data))
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence = 0
        self._flush_every_s = flush_every_s
        self._flushed = time.monotonic()

    def _channel(self, key: str) -> int:
        channel = self._channels.get(key)
        if channel is None:
            found = schema_for_key(key)
            schema = 0
            if found is not None:
                topic = found[0]
                if topic not in self._schemas:
                    self._schemas[topic] = self._writer.register_schema(
                        str(found[1]["title"]), "jsonschema", schema_bytes(topic)
                    )
                schema = self._schemas[topic]
            channel = self._writer.register_channel(key, "json", schema)
            self._channels[key] = channel
        return channel

    def write(self, received: float, key: str, payload: bytes) -> None:
        """Append one message (the chunk is closed when due)."""
        stamp = round(received * 1e9)
        self._sequence += 1
        self._writer.add_message(self._channel(key), stamp, payload, stamp, self._sequence)
        self.flush_if_due()

    def flush(self) -> None:
        """Close the chunk in progress and write it."""
        self._writer.flush()
        self._flushed = time.monotonic()

    def flush_if_due(self) -> None:
        """Close the chunk when it is ``flush_every_s`` old (chunks stay large)."""
        if time.monotonic() - self._flushed >= self._flush_every_s:
            self.flush()

    def close(self) -> None:
        """Write the summary (indexes, statistics) and close the file."""
        self._writer.finish()
        self._file.close()


def open_writer(
    path: Path,
    metadata: Mapping[str, Mapping[str, str]] | None = None,
    flush_every_s: float = FLUSH_EVERY_S,
) -> RecordingWriter:
    """A writer for ``path``: MCAP for ``.mcap``, else JSON lines (no metadata)."""
    path = Path(path)
    if path.suffix == MCAP_SUFFIX:
        return McapWriter(path, metadata, flush_every_s)
    return JsonLinesWriter(path)


@dataclass
class Recording:
    """A recording being read: iterate it for its messages.

    Parameters
    ----------
    path : Path
        The file.

    Attributes
    ----------
    metadata : dict
        The MCAP metadata records read so far (name -> fields).
    stopped : str or None
        After iterating: why reading stopped before the end of the file (a cut or
        corrupt record, a broken line), naming where; ``None`` if the file was whole.
    messages : int
        Messages read so far.
    """

    path: Path
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    stopped: str | None = None
    messages: int = 0

    def __iter__(self) -> Iterator[RecordedMessage]:
        self.stopped, self.messages = None, 0
        if not self.path.is_file():
            raise ConfigError(f"recording: no file {self.path}")
        if self.path.suffix == MCAP_SUFFIX:
            yield from self._mcap()
        else:
            yield from self._json_lines()

    def _mcap(self) -> Iterator[RecordedMessage]:
        from mcap.data_stream import EndOfFile
        from mcap.records import Channel, DataEnd, Footer, Message, Metadata
        from mcap.stream_reader import StreamReader

        channels: dict[int, str] = {}
        ended = False
        with self.path.open("rb") as f:
            records = StreamReader(f, record_size_limit=64 << 20).records
            while True:
                try:
                    record = next(records)
                except StopIteration:
                    break
                except EndOfFile:  # the file ends inside a record: cut, or being written
                    break
                except Exception as exc:  # a corrupt record: stop there
                    self.stopped = _damage(self.path, f.tell(), self.messages, exc)
                    return
                if isinstance(record, Message):
                    key = channels.get(record.channel_id)
                    if key is None:
                        continue
                    self.messages += 1
                    yield RecordedMessage(record.log_time / 1e9, key, record.data, self.messages)
                elif isinstance(record, Channel):
                    channels[record.id] = record.topic
                elif isinstance(record, Metadata):
                    self.metadata[record.name] = dict(record.metadata)
                elif isinstance(record, (DataEnd, Footer)):
                    ended = True
            if not ended:
                self.stopped = (
                    f"{self.path}: ends after message {self.messages} without its summary "
                    "(still being written, or cut)"
                )

    def _json_lines(self) -> Iterator[RecordedMessage]:
        with self.path.open("rb") as f:
            for line_no, text in enumerate(f, 1):
                if not text.strip():
                    continue
                try:
                    obj = orjson.loads(text)
                    received, key = float(obj["t"]), obj["key"]
                    payload = orjson.dumps(obj["msg"])
                    if type(key) is not str:
                        raise TypeError("key is not a string")
                except Exception as exc:
                    what = "an incomplete line" if not text.endswith(b"\n") else str(exc)
                    self.stopped = f"{self.path}: stopped at line {line_no}: {what}"
                    return
                self.messages += 1
                yield RecordedMessage(received, key, payload, self.messages)


def _damage(path: Path, offset: int, messages: int, exc: BaseException) -> str:
    size = os.path.getsize(path)
    what = type(exc).__name__ + (f": {exc}" if str(exc) else "")
    return (
        f"{path}: stopped after message {messages}, near byte {offset} of {size} "
        f"(a cut or corrupt record: {what})"
    )


def read_recording(path: Path) -> Recording:
    """A recording to iterate (MCAP or JSON lines, by suffix)."""
    return Recording(Path(path))
