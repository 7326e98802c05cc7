"""Zones and doors on the floor: who is in which zone, who crossed which door.

Shared by the analytics (time in zones, entries, crossings over a recording) and the
output's zones sink (enter and leave events, live). A zone is a polygon
(:class:`~openptrack_py.config.ZoneConfig`), a door a segment
(:class:`~openptrack_py.config.DoorConfig`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from openptrack_py.config import DoorConfig, ZoneConfig

__all__ = ["ZoneTracker", "crossing", "inside"]


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
