"""Who is alive on a site and how busy they are (``openptrack status``, launcher summary)."""

from __future__ import annotations

import threading
import time

from openptrack_py.errors import WireFormatError
from openptrack_py.messages.codec import decode_node_stats
from openptrack_py.messages.stats import NodeStats
from openptrack_py.transport.base import Bus, Closable, Sample
from openptrack_py.transport.keys import SiteKeys


class StatusBoard:
    """Collects liveliness and the latest stats of every node of a site.

    Parameters
    ----------
    bus : Bus
        Session to listen on.
    site : str
        Site name.
    """

    def __init__(self, bus: Bus, site: str = "default") -> None:
        self.keys = SiteKeys(site)
        self._lock = threading.Lock()
        self.alive: set[str] = set()
        self.stats: dict[str, NodeStats] = {}
        self.malformed = 0
        self._subs: list[Closable] = [
            bus.subscribe_liveliness(self.keys.alive("*"), self._on_alive),
            bus.subscribe(self.keys.stats("*"), self._on_stats),
        ]

    def _on_alive(self, key: str, alive: bool) -> None:
        name = key.rsplit("/", 1)[-1]
        with self._lock:
            if alive:
                self.alive.add(name)
            else:
                self.alive.discard(name)

    def _on_stats(self, sample: Sample) -> None:
        try:
            stats = decode_node_stats(sample.payload)
        except WireFormatError:
            with self._lock:
                self.malformed += 1
            return
        with self._lock:
            self.stats[stats.node] = stats

    def close(self) -> None:
        """Stop listening."""
        for sub in self._subs:
            sub.close()

    def rows(self) -> list[dict[str, object]]:
        """One row per known node (alive or with stats), sorted by name."""
        now = time.time()
        with self._lock:
            names = sorted(self.alive | set(self.stats))
            rows = []
            for name in names:
                s = self.stats.get(name)
                rates = s.rates_hz if s else {}
                counters = s.counters if s else {}
                rows.append(
                    {
                        "node": name,
                        "alive": name in self.alive,
                        "host": s.host if s else "",
                        "pid": s.pid if s else None,
                        "uptime_s": round(s.uptime_s, 1) if s else None,
                        "in_hz": rates.get("in"),
                        "out_hz": rates.get("out"),
                        "dropped": counters.get("dropped"),
                        "malformed": counters.get("malformed"),
                        "stats_age_s": round(now - s.stamp, 1) if s else None,
                    }
                )
        return rows

    def summary_line(self) -> str:
        """A compact one-line summary: ``sim out 92.0/s | record in 92.0/s``."""
        parts = []
        for row in self.rows():
            bits = [str(row["node"])]
            if not row["alive"]:
                bits.append("(gone)")
            for key, label in (("in_hz", "in"), ("out_hz", "out")):
                value = row[key]
                if value:
                    bits.append(f"{label} {value:.1f}/s")
            for key in ("dropped", "malformed"):
                if row[key]:
                    bits.append(f"{key} {row[key]}")
            parts.append(" ".join(bits))
        return " | ".join(parts) if parts else "no nodes seen yet"
