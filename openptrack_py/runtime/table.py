"""A live terminal view of a site: the tracks people are getting, and every node's rates."""

from __future__ import annotations

import threading
import time

from openptrack_py.errors import WireFormatError
from openptrack_py.messages.codec import decode_track_batch
from openptrack_py.messages.track import TrackBatch, Visibility
from openptrack_py.runtime.status import StatusBoard
from openptrack_py.transport.base import Bus, Sample
from openptrack_py.transport.keys import SiteKeys


class TrackView:
    """Keeps the latest smoothed (or, without an output node, raw) tracks of a site.

    Parameters
    ----------
    bus : Bus
        Session to listen on.
    site : str
        Site name.
    """

    def __init__(self, bus: Bus, site: str = "default") -> None:
        keys = SiteKeys(site)
        self._lock = threading.Lock()
        self._latest: dict[str, tuple[float, TrackBatch]] = {}
        self._subs = [
            bus.subscribe(keys.tracks_smoothed, lambda s: self._on(s, "smoothed")),
            bus.subscribe(keys.tracks, lambda s: self._on(s, "raw")),
        ]

    def _on(self, sample: Sample, kind: str) -> None:
        try:
            batch = decode_track_batch(sample.payload)
        except WireFormatError:
            return
        with self._lock:
            self._latest[kind] = (time.monotonic(), batch)

    def latest(self, max_age_s: float = 2.0) -> tuple[str, TrackBatch] | None:
        """``("smoothed" | "raw", batch)``, preferring fresh smoothed tracks."""
        now = time.monotonic()
        with self._lock:
            for kind in ("smoothed", "raw"):
                item = self._latest.get(kind)
                if item is not None and now - item[0] <= max_age_s:
                    return kind, item[1]
        return None

    def close(self) -> None:
        """Stop listening."""
        for sub in self._subs:
            sub.close()


def render(view: TrackView, board: StatusBoard, limit: int = 20) -> str:
    """The table as text."""
    lines = []
    latest = view.latest()
    if latest is None:
        lines.append("no tracks received yet")
    else:
        kind, batch = latest
        lines.append(f"{len(batch.tracks)} people tracked ({kind}, frame {batch.seq})")
        if batch.tracks:
            lines.append(
                f"{'id':>5} {'x':>7} {'y':>7} {'height':>7} {'speed':>6} {'age':>7}  seen"
            )
        for t in sorted(batch.tracks, key=lambda t: t.id)[:limit]:
            speed = (t.vx**2 + t.vy**2) ** 0.5
            seen = "yes" if t.visibility == Visibility.VISIBLE else "no"
            numbers = f"{t.x:>7.2f} {t.y:>7.2f} {t.height:>7.2f} {speed:>6.2f} {t.age:>7.1f}"
            lines.append(f"{t.id:>5} {numbers}  {seen}")
        if len(batch.tracks) > limit:
            lines.append(f"  ... and {len(batch.tracks) - limit} more")
    lines.append("nodes: " + board.summary_line())
    return "\n".join(lines)
