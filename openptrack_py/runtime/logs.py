"""Structured logging for nodes, and a rate limiter for repetitive warnings.

Text lines look like ``12:00:01.234 WARNING sim: dropped batch sensor=k1 seq=12``;
``--log-format json`` gives one JSON object per line instead. Fields come from
``extra={"fields": {...}}``.
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from collections.abc import Callable

import orjson

_STANDARD = frozenset(logging.LogRecord("", 0, "", 0, "", (), None).__dict__) | {"message"}


class _TextFormatter(logging.Formatter):
    def __init__(self, node: str) -> None:
        super().__init__()
        self.node = node

    def format(self, record: logging.LogRecord) -> str:
        stamp = time.strftime("%H:%M:%S", time.localtime(record.created))
        fields = getattr(record, "fields", None) or {}
        tail = "".join(f" {k}={v}" for k, v in fields.items())
        text = f"{stamp}.{int(record.msecs):03d} {record.levelname} {self.node}: "
        text += record.getMessage() + tail
        if record.exc_info:
            text += "\n" + self.formatException(record.exc_info)
        return text


class _JsonFormatter(logging.Formatter):
    def __init__(self, node: str) -> None:
        super().__init__()
        self.node = node

    def format(self, record: logging.LogRecord) -> str:
        item = {
            "t": round(record.created, 6),
            "level": record.levelname,
            "node": self.node,
            "logger": record.name,
            "msg": record.getMessage(),
        }
        item.update(getattr(record, "fields", None) or {})
        if record.exc_info:
            item["exc"] = self.formatException(record.exc_info)
        return orjson.dumps(item, default=str).decode()


LOG_LEVELS = ("debug", "info", "warning", "error")


def configure_logging(node: str, level: str = "info", fmt: str = "text") -> None:
    """Send this process's logs to stderr in the chosen format.

    Parameters
    ----------
    node : str
        Name shown on every line.
    level : {"debug", "info", "warning", "error"}
        Minimum level.
    fmt : {"text", "json"}
        Line format.
    """
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_JsonFormatter(node) if fmt == "json" else _TextFormatter(node))
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(level.upper())


class RateLimitedLog:
    """Log at most one message per ``interval_s`` for each ``topic``.

    Suppressed messages are counted and the count is reported with the next one that
    gets through, so a flood of bad input costs one line every few seconds.

    Parameters
    ----------
    logger : logging.Logger
        Where to log.
    interval_s : float
        Minimum time between two lines of the same topic.
    clock : callable
        Monotonic time source (injectable for tests).
    """

    def __init__(
        self,
        logger: logging.Logger,
        interval_s: float = 5.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.logger = logger
        self.interval_s = interval_s
        self.clock = clock
        self._last: dict[str, float] = {}
        self._suppressed: dict[str, int] = {}
        self._lock = threading.Lock()

    def warning(self, topic: str, msg: str, **fields: object) -> bool:
        """Log ``msg`` unless ``topic`` was logged recently; return whether it was."""
        now = self.clock()
        with self._lock:
            last = self._last.get(topic)
            if last is not None and now - last < self.interval_s:
                self._suppressed[topic] = self._suppressed.get(topic, 0) + 1
                return False
            self._last[topic] = now
            suppressed = self._suppressed.pop(topic, 0)
        if suppressed:
            fields["suppressed"] = suppressed
        self.logger.warning(msg, extra={"fields": fields})
        return True
