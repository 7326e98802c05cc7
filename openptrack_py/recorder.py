"""Record messages to a JSON-lines file, one validated message per line.

Each line is ``{"t": <receive time>, "key": "<key>", "msg": <the message as sent>}``.
Messages that fail validation are counted as malformed and not written, so a
recording only ever holds messages that decode.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import IO

import orjson

from openptrack_py.errors import ConfigError
from openptrack_py.messages.by_key import TOPICS, decoder_for_key
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


def _validated_by(expr: str):
    decode = decoder_for_key(expr)
    if decode is None:
        raise ConfigError(
            f"recorder.keys: {expr!r} names no known topic (allowed: {', '.join(TOPICS)})"
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

    Raises
    ------
    ConfigError
        If a key expression names no known topic.
    """

    def __init__(self, node: Node, path: Path, keyexprs: list[str]) -> None:
        self.node = node
        self.lines = 0
        validators = [(expr, _validated_by(expr)) for expr in keyexprs]
        self.path = unique_path(Path(path))
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._inbox: Inbox[Received[bytes]] = Inbox(
            100_000, on_drop=lambda: node.counters.inc("dropped")
        )
        for expr, validate in validators:
            node.subscribe(expr, validate, inbox=self._inbox)

    def _write(self, out: IO[bytes], items: list[Received[bytes]]) -> None:
        for item in items:
            out.write(b'{"t":' + orjson.dumps(item.received) + b',"key":' + orjson.dumps(item.key))
            out.write(b',"msg":' + item.message + b"}\n")
            self.lines += 1
            self.node.counters.inc("out")
        if items:
            out.flush()  # what was received is on disk before the next wait

    def run(self) -> None:
        """Write until the node stops, then write what is still queued."""
        self.node.log.info("recording", extra={"fields": {"path": str(self.path)}})
        with self.path.open("ab") as out:
            while self.node.running:
                self._write(out, self._inbox.drain(timeout=0.2))
            self._write(out, self._inbox.drain(timeout=0))


def read_recording(path: Path) -> list[dict]:
    """Load a recording written by :class:`Recorder`."""
    with Path(path).open("rb") as f:
        return [orjson.loads(line) for line in f if line.strip()]
