"""Places on the floor: time in zones, crossings of doors, where people were.

:class:`ZoneTracker` knows which zones each person is in and reports the changes (what
a live zones sink turns into enter/leave events), :class:`PlaceTally` adds up, as
frames stream in: each person's dwell time per zone and the zone's entries, each door's
crossings in and out (a person's step that crosses the door's segment), and the
occupancy heatmap (person-seconds per ``cell_m`` cell), all in memory that does not
grow with the recording.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from openptrack_py.config import DoorConfig, ZoneConfig

__all__ = ["DoorSummary", "PlaceTally", "ZoneSummary", "ZoneTracker", "crossing", "inside"]


def inside(polygon: np.ndarray, x: float, y: float) -> bool:
    """Whether ``(x, y)`` is inside ``polygon`` (``(n, 2)``; even-odd rule)."""
    px, py = polygon[:, 0], polygon[:, 1]
    qx, qy = np.roll(px, -1), np.roll(py, -1)
    straddle = (py > y) != (qy > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        at = px + (y - py) * (qx - px) / (qy - py)
    return bool(np.count_nonzero(straddle & (x < at)) % 2)


def crossing(door: DoorConfig, p: tuple[float, float], q: tuple[float, float]) -> int:
    """+1 if the step ``p -> q`` enters through ``door``, -1 if it leaves, else 0."""
    (ax, ay), (bx, by) = door.a, door.b

    def side(x: float, y: float) -> float:
        return (bx - ax) * (y - ay) - (by - ay) * (x - ax)  # > 0: left of a -> b

    # the line itself counts as the left side, so a step that ends on it and the next
    # that leaves it make one crossing, not none or two
    sp, sq = side(*p) >= 0, side(*q) >= 0
    if sp == sq:
        return 0
    # does the step cross the segment itself, not its line beyond the ends?
    dx, dy = q[0] - p[0], q[1] - p[1]
    ta = dx * (ay - p[1]) - dy * (ax - p[0])
    tb = dx * (by - p[1]) - dy * (bx - p[0])
    if ta * tb > 0:
        return 0
    return 1 if sq else -1


class ZoneTracker:
    """Which zones each person is in, and what changed with each frame.

    Parameters
    ----------
    zones : sequence of ZoneConfig
        The zones.
    hold_s : float
        A person missing from the frames this long or less keeps their zones (a
        tracker drops a track for a moment without the person leaving).
    """

    def __init__(self, zones: Sequence[ZoneConfig], hold_s: float = 1.0) -> None:
        self.zones = list(zones)
        self.hold_s = hold_s
        self._polygons = [np.array(z.polygon, dtype=float) for z in self.zones]
        self.current: dict[int, set[str]] = {}
        self._seen: dict[int, float] = {}

    def update(
        self, t: float, positions: dict[int, tuple[float, float]]
    ) -> tuple[list[tuple[int, str]], list[tuple[int, str]]]:
        """Take everyone's positions at ``t``; return ``(entered, left)`` (person, zone) pairs.

        A person missing from ``positions`` for more than ``hold_s`` leaves every zone
        they were in.
        """
        entered: list[tuple[int, str]] = []
        left: list[tuple[int, str]] = []
        now: dict[int, set[str]] = {}
        for key, (x, y) in positions.items():
            self._seen[key] = t
            now[key] = {
                z.name for z, poly in zip(self.zones, self._polygons, strict=True)
                if inside(poly, x, y)
            }  # fmt: skip
        for key, names in self.current.items():
            if key not in now and t - self._seen.get(key, t) <= self.hold_s:
                now[key] = names  # briefly unseen: still there
        for key in set(now) | set(self.current):
            before, after = self.current.get(key, set()), now.get(key, set())
            entered += [(key, z) for z in sorted(after - before)]
            left += [(key, z) for z in sorted(before - after)]
        self.current = {k: v for k, v in now.items() if v}
        self._seen = {k: v for k, v in self._seen.items() if t - v <= self.hold_s}
        return entered, left

    def counts(self) -> dict[str, int]:
        """People in each zone now."""
        out = {z.name: 0 for z in self.zones}
        for names in self.current.values():
            for name in names:
                out[name] += 1
        return out


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
