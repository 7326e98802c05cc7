"""Places on the floor: time in zones, crossings of doors, where people were.

:class:`PlaceTally` adds up, as frames stream in (with :mod:`openptrack_py.zones` for
who is in which zone and who crossed a door): each person's dwell time per zone and the
zone's entries, each door's crossings in and out (a person's step that crosses the
door's segment), and the occupancy heatmap (person-seconds per ``cell_m`` cell), all in
memory that does not grow with the recording.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from openptrack_py.config import DoorConfig, ZoneConfig
from openptrack_py.zones import ZoneTracker, crossing

__all__ = ["DoorSummary", "PlaceTally", "ZoneSummary"]


@dataclass
class ZoneSummary:
    """A zone over a recording: entries, and each person's time in it (seconds)."""

    name: str
    entries: int
    dwell_s: dict[int, float]
    peak_count: int

    def row(self) -> dict[str, object]:
        """The figures as a table row."""
        total = sum(self.dwell_s.values())
        return {
            "zone": self.name,
            "entries": self.entries,
            "people": len(self.dwell_s),
            "person_s": round(total, 1),
            "peak_count": self.peak_count,
        }


@dataclass
class DoorSummary:
    """A door over a recording: crossings in and out."""

    name: str
    entries: int
    exits: int

    def row(self) -> dict[str, object]:
        """The figures as a table row."""
        return {"door": self.name, "in": self.entries, "out": self.exits}


@dataclass
class PlaceTally:
    """Accumulates zones, doors and the heatmap, frame by frame (see the module).

    Parameters
    ----------
    zones, doors : sequence
        The network's zones and doors.
    cell_m : float
        Heatmap cell side, metres.
    max_gap_s : float
        A person unseen longer than this does not cross a door between the sightings.
    """

    zones: Sequence[ZoneConfig] = ()
    doors: Sequence[DoorConfig] = ()
    cell_m: float = 0.25
    max_gap_s: float = 1.0
    heat: dict[tuple[int, int], float] = field(default_factory=dict)
    _zone_tracker: ZoneTracker | None = None
    _dwell: dict[str, dict[int, float]] = field(default_factory=dict)
    _entries: dict[str, int] = field(default_factory=dict)
    _peak: dict[str, int] = field(default_factory=dict)
    _doors: dict[str, list[int]] = field(default_factory=dict)
    _last: dict[int, tuple[float, float, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._zone_tracker = ZoneTracker(self.zones, self.max_gap_s)
        self._dwell = {z.name: {} for z in self.zones}
        self._entries = {z.name: 0 for z in self.zones}
        self._peak = {z.name: 0 for z in self.zones}
        self._doors = {d.name: [0, 0] for d in self.doors}

    def add(self, t: float, positions: dict[int, tuple[float, float]], dt: float) -> None:
        """Everyone's position at ``t``, for ``dt`` seconds of the recording."""
        for x, y in positions.values():
            cell = (math.floor(x / self.cell_m), math.floor(y / self.cell_m))
            self.heat[cell] = self.heat.get(cell, 0.0) + dt
        zones = self._zone_tracker
        assert zones is not None
        entered, _left = zones.update(t, positions)
        for _key, name in entered:
            self._entries[name] += 1
        for name, count in zones.counts().items():
            self._peak[name] = max(self._peak[name], count)
        for key, names in zones.current.items():
            if key not in positions:
                continue  # held in its zones while briefly unseen, but not timed
            for name in names:
                self._dwell[name][key] = self._dwell[name].get(key, 0.0) + dt
        for key, (x, y) in positions.items():
            last = self._last.get(key)
            if last is not None and t - last[0] <= self.max_gap_s:
                for door in self.doors:
                    way = crossing(door, (last[1], last[2]), (x, y))
                    if way:
                        self._doors[door.name][0 if way > 0 else 1] += 1
            self._last[key] = (t, x, y)
        if len(self._last) > 4 * max(len(positions), 64):  # forget people long gone
            self._last = {k: v for k, v in self._last.items() if t - v[0] <= self.max_gap_s}

    def zone_summaries(self) -> list[ZoneSummary]:
        """Each zone's figures so far."""
        return [
            ZoneSummary(z.name, self._entries[z.name], dict(self._dwell[z.name]),
                        self._peak[z.name])
            for z in self.zones
        ]  # fmt: skip

    def door_summaries(self) -> list[DoorSummary]:
        """Each door's crossings so far."""
        return [DoorSummary(d.name, *self._doors[d.name]) for d in self.doors]

    def heatmap(self) -> tuple[np.ndarray, tuple[float, float]]:
        """Person-seconds per cell as a grid (rows along y) and the grid's corner."""
        if not self.heat:
            return np.zeros((0, 0)), (0.0, 0.0)
        cells = np.array(list(self.heat), dtype=int)
        lo = cells.min(axis=0)
        shape = cells.max(axis=0) - lo + 1
        grid = np.zeros((shape[1], shape[0]))
        for (i, j), value in self.heat.items():
            grid[j - lo[1], i - lo[0]] = value
        return grid, (lo[0] * self.cell_m, lo[1] * self.cell_m)
