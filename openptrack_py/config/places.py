"""The ``zones`` and ``doors`` sections: named places on the floor, for analytics and events.

A zone is a polygon on the floor (world frame, metres), a door a line segment people
cross. ``openptrack analyze`` reports each person's time in each zone and the crossings
of each door; an output's ``zones`` sink sends enter/leave events and counts live.
"""

from __future__ import annotations

import math

from pydantic import Field, field_validator

from openptrack_py.config.base import Name, StrictModel

__all__ = ["DoorConfig", "ZoneConfig"]

Point = tuple[float, float]


def _finite(points: list[Point], what: str) -> list[Point]:
    for x, y in points:
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"{what}: every point must be finite, got ({x}, {y})")
    return points


class ZoneConfig(StrictModel):
    """A named area of the floor.

    Parameters
    ----------
    name : str
        Its name (in reports, OSC addresses and event messages).
    polygon : list of (float, float)
        Its corners in order (at least 3), world metres; the polygon closes by itself.
    """

    name: Name
    polygon: list[Point] = Field(min_length=3, max_length=256)

    @field_validator("polygon")
    @classmethod
    def _area(cls, value: list[Point]) -> list[Point]:
        _finite(value, "polygon")
        x = [p[0] for p in value]
        y = [p[1] for p in value]
        n = len(value)
        area = 0.5 * abs(sum(x[i] * y[(i + 1) % n] - x[(i + 1) % n] * y[i] for i in range(n)))
        if area < 1e-6:
            raise ValueError("polygon: its corners enclose no area")
        return value


class DoorConfig(StrictModel):
    """A doorway: a segment of the floor that people cross.

    Parameters
    ----------
    name : str
        Its name.
    a, b : (float, float)
        Its ends, world metres. Walking from ``a`` to ``b``, a crossing from the right
        side to the left is an entry (``in``), from left to right an exit (``out``).
    """

    name: Name
    a: Point
    b: Point

    @field_validator("b")
    @classmethod
    def _length(cls, value: Point, info: object) -> Point:
        _finite([value], "b")
        a = getattr(info, "data", {}).get("a")
        if a is not None and math.hypot(value[0] - a[0], value[1] - a[1]) < 1e-3:
            raise ValueError("b: a door's ends must be at least 1 mm apart")
        return value
