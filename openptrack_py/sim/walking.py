"""Where simulated walkers go: the point inside a door, and the way round furniture.

Directors steer people with :meth:`~openptrack_py.sim.world.World.seek`, straight at a
goal; the social force keeps them off walls, furniture and each other. Walking straight
at a goal behind a block of furniture leaves a walker pressed against it, so
:func:`steer_around` picks the next corner of the shortest way round instead.
"""

from __future__ import annotations

import numpy as np

from openptrack_py.sim.world import Room


def _segment_hits_box(
    a: np.ndarray, b: np.ndarray, box: tuple[float, float, float, float]
) -> bool:
    """Whether the segment ``a``-``b`` passes through ``box`` ``(x0, y0, x1, y1)``."""
    x0, y0, x1, y1 = box
    d = b - a
    t0, t1 = 0.0, 1.0
    for p, q in ((-d[0], a[0] - x0), (d[0], x1 - a[0]), (-d[1], a[1] - y0), (d[1], y1 - a[1])):
        if abs(p) < 1e-12:
            if q < 0:
                return False
            continue
        r = q / p
        if p < 0:
            t0 = max(t0, r)
        else:
            t1 = min(t1, r)
        if t0 > t1:
            return False
    return True


def steer_around(room: Room, pos: np.ndarray, goal: np.ndarray, radius: float) -> np.ndarray:
    """Where to walk now to reach ``goal``: ``goal``, or a corner of the furniture in the way.

    Walking straight at a goal behind a block of furniture leaves a social-force walker
    pressed against it. This takes the shortest way through the corners of the furniture
    (``radius`` + 0.3 m out) that sees past it, and returns its first point more than
    0.3 m away.
    """
    margin = 0.9 * radius
    boxes = [(o.x0 - margin, o.y0 - margin, o.x1 + margin, o.y1 + margin) for o in room.obstacles]

    def clear(a: np.ndarray, b: np.ndarray) -> bool:
        return not any(_segment_hits_box(a, b, box) for box in boxes)

    if clear(pos, goal):
        return goal
    pad = radius + 0.3
    corners = [
        np.array(c)
        for o in room.obstacles
        for c in ((o.x0 - pad, o.y0 - pad), (o.x0 - pad, o.y1 + pad),
                  (o.x1 + pad, o.y0 - pad), (o.x1 + pad, o.y1 + pad))
        if room.contains(np.array(c), radius)[0]
    ]  # fmt: skip
    nodes = [pos, *corners, goal]
    n = len(nodes)
    cost = np.full(n, np.inf)
    cost[0] = 0.0
    previous = [-1] * n
    done = np.zeros(n, dtype=bool)
    for _ in range(n):  # Dijkstra on the visibility graph
        i = int(np.argmin(np.where(done, np.inf, cost)))
        if not np.isfinite(cost[i]) or i == n - 1:
            break
        done[i] = True
        for j in range(n):
            if not done[j] and clear(nodes[i], nodes[j]):
                c = cost[i] + float(np.linalg.norm(nodes[j] - nodes[i]))
                if c < cost[j]:
                    cost[j], previous[j] = c, i
    if not np.isfinite(cost[-1]):
        return goal  # no way round: walk at it and let the forces sort it out
    path = [n - 1]
    while previous[path[-1]] > 0:
        path.append(previous[path[-1]])
    for k in reversed(path):
        if np.linalg.norm(nodes[k] - pos) > 0.3:
            return nodes[k]
    return goal


def door_inside(room: Room, door: tuple[float, float], margin: float = 0.3) -> np.ndarray:
    """The point just inside ``door``, ``margin`` metres from the walls."""
    x, y = door
    return np.array(
        [np.clip(x, margin, room.width - margin), np.clip(y, margin, room.depth - margin)]
    )
