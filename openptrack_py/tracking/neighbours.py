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
