"""Record a site's messages to a file: MCAP (``.mcap``) or JSON lines (``.jsonl``).

Every valid message on the chosen keys goes to the file with its receive time and key
(:mod:`openptrack_py.recordings.files`): an MCAP file has one channel per key with its
message schema and starts with metadata (the site, the keys, and the network file, so
``openptrack retrack`` runs the tracker the site ran); a JSON-lines file has one
``{"t", "key", "msg"}`` object per line. Messages that fail validation are counted as
malformed and not written, so a recording only ever holds messages that decode.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from pathlib import Path

from openptrack_py.calibration.files import parse_entry_payload
from openptrack_py.errors import CalibrationError, ConfigError, WireFormatError
from openptrack_py.messages.by_key import TOPICS, decoder_for_key
from openptrack_py.recordings import RecordingWriter, open_writer
from openptrack_py.runtime.node import Inbox, Node, Received


def unique_path(path: Path) -> Path:
    """``path``, or ``path`` with a timestamp before the suffix if it already exists."""
    if not path.exists():
        return path
    stamp = time.strftime("%Y%m%d-%H%M%S")
    candidate = path.with_name(f"{path.stem}-{stamp}{path.suffix}")
    n = 1
    while candidate.exists():
        candidate = path.with_name(f"{path.stem}-{stamp}-{n}{path.suffix}")
        n += 1
    return candidate


def _calibration_entry(payload: bytes) -> object:
    try:
        return parse_entry_payload(payload)
    except CalibrationError as exc:  # counted as malformed, like any bad message
        raise WireFormatError(str(exc)) from None


def _validated_by(expr: str):
    chunks = expr.split("/")
    is_calibration = len(chunks) >= 3 and chunks[2] == "calibration"
    decode = _calibration_entry if is_calibration else decoder_for_key(expr)
    if decode is None:
        raise ConfigError(
            f"recorder.keys: {expr!r} names no known topic "
            f"(allowed: {', '.join([*TOPICS, 'calibration'])})"
        )

    def validate(payload: bytes) -> bytes:
        decode(payload)
        return payload

    return validate


class Recorder:
    """Subscribes to key expressions and appends every valid message to a file.

    Parameters
    ----------
    node : Node
        Node whose bus and counters to use.
    path : Path
        Output file (an existing file is never overwritten).
    keyexprs : list of str
        Full key expressions to record, each below a known topic
        (``opt/<site>/detections/**``, ``opt/<site>/tracks``...).
    metadata : mapping of str to mapping, optional
        Further metadata records for an MCAP file (e.g. ``network``: the network file).

    Raises
    ------
    ConfigError
        If a key expression names no known topic.
    """

    def __init__(
        self,
        node: Node,
        path: Path,
        keyexprs: list[str],
        metadata: Mapping[str, Mapping[str, str]] | None = None,
    ) -> None:
        self.node = node
        self.lines = 0
        self.metadata = dict(metadata or {})
        validators = [(expr, _validated_by(expr)) for expr in keyexprs]
        self.keyexprs = list(keyexprs)
        self.path = unique_path(Path(path))
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._inbox: Inbox[Received[bytes]] = Inbox(
            100_000, on_drop=lambda: node.counters.inc("dropped")
        )
        for expr, validate in validators:
            node.subscribe(expr, validate, inbox=self._inbox)

    def _write(self, out: RecordingWriter, items: list[Received[bytes]]) -> None:
        for item in items:
            out.write(item.received, item.key, item.message)
            self.lines += 1
            self.node.counters.inc("out")
        out.flush_if_due()  # in the file within flush_every_s, also when traffic stops

    def run(self) -> None:
        """Write until the node stops, then write what is still queued."""
        self.node.log.info("recording", extra={"fields": {"path": str(self.path)}})
        info = {
            "site": self.node.keys.site,
            "keys": " ".join(self.keyexprs),
            "started": f"{time.time():.6f}",
        }
        out = open_writer(self.path, {"openptrack": info, **self.metadata})
        try:
            while self.node.running:
                self._write(out, self._inbox.drain(timeout=0.2))
            self._write(out, self._inbox.drain(timeout=0))
        finally:
            out.close()
