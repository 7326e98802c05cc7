"""Key expressions of a site (docs/design.md §1), and key-expression matching.

Every process-crossing message lives under ``opt/<site>/``. Matching follows Zenoh's
rules for the wildcards used here: ``*`` matches exactly one non-empty chunk and ``**``
matches any number of chunks, including none.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache

_CHUNK_RE = re.compile(r"^[^/*$#?]+$")


@dataclass(frozen=True)
class SiteKeys:
    """Key expressions of one site.

    Parameters
    ----------
    site : str
        Site name (``default`` unless configured).
    """

    site: str = "default"

    @property
    def prefix(self) -> str:
        """``opt/<site>``."""
        return f"opt/{self.site}"

    def detections(self, sensor_id: str = "*") -> str:
        """Detections of one sensor (or ``*``: all sensors)."""
        return f"{self.prefix}/detections/{sensor_id}"

    @property
    def tracks(self) -> str:
        """Raw tracks, one message per tracker step."""
        return f"{self.prefix}/tracks"

    @property
    def tracks_smoothed(self) -> str:
        """Smoothed tracks at the output's fixed rate."""
        return f"{self.prefix}/tracks/smoothed"

    @property
    def ground_truth(self) -> str:
        """Simulator ground truth."""
        return f"{self.prefix}/ground_truth"

    def calibration(self, sensor_id: str = "*") -> str:
        """Calibration of one sensor (queryable)."""
        return f"{self.prefix}/calibration/{sensor_id}"

    def board(self, sensor_id: str = "*") -> str:
        """What one sensor sees of the checkerboard during a calibration session."""
        return f"{self.prefix}/board/{sensor_id}"

    @property
    def board_progress(self) -> str:
        """Progress of a live checkerboard session (for the web view)."""
        return f"{self.prefix}/board_progress"

    def config(self, node: str = "*") -> str:
        """Live parameter updates of one node."""
        return f"{self.prefix}/config/{node}"

    def config_ack(self, node: str = "*") -> str:
        """Answers of one node to live parameter updates."""
        return f"{self.prefix}/config/{node}/ack"

    def alive(self, node: str = "*") -> str:
        """Liveliness token of one node."""
        return f"{self.prefix}/alive/{node}"

    def stats(self, node: str = "*") -> str:
        """Counters of one node."""
        return f"{self.prefix}/stats/{node}"

    def relative(self, suffix: str) -> str:
        """``opt/<site>/<suffix>``."""
        return f"{self.prefix}/{suffix.lstrip('/')}"


def validate_key(key: str, *, allow_wildcards: bool = False) -> str:
    """Check that ``key`` is a well-formed key (expression).

    Raises
    ------
    ValueError
        Naming the offending chunk.
    """
    if not key or key.startswith("/") or key.endswith("/"):
        raise ValueError(f"key {key!r}: must be non-empty and not start or end with '/'")
    for chunk in key.split("/"):
        if allow_wildcards and chunk in ("*", "**"):
            continue
        if not _CHUNK_RE.match(chunk):
            raise ValueError(f"key {key!r}: invalid chunk {chunk!r}")
    return key


@lru_cache(maxsize=8192)
def _match(expr: tuple[str, ...], key: tuple[str, ...]) -> bool:
    if not expr:
        return not key
    head, rest = expr[0], expr[1:]
    if head == "**":
        return any(_match(rest, key[i:]) for i in range(len(key) + 1))
    if not key:
        return False
    return (head == "*" or head == key[0]) and _match(rest, key[1:])


def key_matches(expr: str, key: str) -> bool:
    """Whether the concrete ``key`` is matched by the key expression ``expr``."""
    if "*" not in expr:
        return expr == key
    return _match(tuple(expr.split("/")), tuple(key.split("/")))
