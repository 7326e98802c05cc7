"""Which tracks and detections are near each other on the floor, without all-pairs arrays.

A k-d tree (:class:`scipy.spatial.cKDTree`) answers "which pairs are within ``r``" and
"how far is the nearest" in about ``n log n``, where the all-pairs distance matrix costs
``n^2`` (a crowd of a hundred people is ten thousand pairs at every step).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def close_pairs(xy: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs ``(i, j)``, ``i < j``, of the points ``xy (n, 2)`` at most ``r`` apart."""
    if len(xy) < 2:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    pairs = cKDTree(xy).query_pairs(r, output_type="ndarray")
    if not len(pairs):
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    return pairs[:, 0], pairs[:, 1]


def nearest_distance(points: np.ndarray, to: np.ndarray) -> np.ndarray:
    """Distance from each of ``points (n, 2)`` to the nearest of ``to (m, 2)`` (inf if none)."""
    if not len(to):
        return np.full(len(points), np.inf)
    if not len(points):
        return np.zeros(0)
    dist, _ = cKDTree(to).query(points, k=1)
    return np.asarray(dist, dtype=float)


def count_within(points: np.ndarray, to: np.ndarray, r: float) -> np.ndarray:
    """How many of ``to (m, 2)`` are at most ``r`` from each of ``points (n, 2)``."""
    if not len(to) or not len(points):
        return np.zeros(len(points), dtype=np.intp)
    return np.asarray(cKDTree(to).query_ball_point(points, r, return_length=True), dtype=np.intp)


def far_pairs(
    points: np.ndarray, to: np.ndarray, r: float, limit: int
) -> tuple[np.ndarray, np.ndarray]:
    """The first ``limit`` pairs ``(i, j)``, row-major, with ``points[i]`` far from ``to[j]``.

    Far: more than ``r`` apart. Row by row, stopping once ``limit`` are found: where
    most pairs are far (a room of people), the first rows give them all, and the full
    ``n x m`` distances are never formed.
    """
    rows: list[np.ndarray] = []
    cols: list[np.ndarray] = []
    need = limit
    for i in range(len(points)):
        if need <= 0:
            break
        d = points[i] - to
        j = np.flatnonzero(d[:, 0] ** 2 + d[:, 1] ** 2 > r**2)[:need]
        rows.append(np.full(len(j), i, dtype=np.intp))
        cols.append(j)
        need -= len(j)
    if not rows:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    return np.concatenate(rows), np.concatenate(cols)
