"""Recordings of a site's messages: MCAP or JSON-lines files, written and read as streams."""

from openptrack_py.recordings.files import (
    JsonLinesWriter,
    McapWriter,
    RecordedMessage,
    Recording,
    RecordingWriter,
    open_writer,
    read_recording,
)
from openptrack_py.recordings.schemas import SCHEMAS, schema_for_key

__all__ = [
    "SCHEMAS",
    "JsonLinesWriter",
    "McapWriter",
    "RecordedMessage",
    "Recording",
    "RecordingWriter",
    "open_writer",
    "read_recording",
    "schema_for_key",
]
