"""Where each sensor stands, learned from its detections, and who hides whom from it.

A track that a sensor covers but does not detect is weaker evidence of a person, unless
someone stands between: in a crowd a person is hidden from a sensor by the people in
front for seconds at a time (the OpenPTrack paper, Table 2: a Kinect v2 misses 29.5 %
of the people of its Crowd sequence, most of them occluded). Counting those frames as
misses would take a real person's track for a lost one.

The tracker is not told where the sensors are; every detection says how far from its
sensor it is (``Detection.distance``, the range to the centroid). With the sensor at
``s`` on the floor and ``h`` above the centroids, a detection at ``p`` of range ``d``
satisfies ``|p - s|^2 + h^2 = d^2``, which is linear in ``(s, c = |s|^2 + h^2)``:
``2 p . s - c = |p|^2 - d^2``. :class:`Viewpoints` accumulates those equations per
sensor and solves them by least squares once the detections are spread enough to fix
``s``; ``h = sqrt(c - |s|^2)`` is how high above the centroids it looks from.

:func:`hidden` then tells which tracks are behind another, seen from the sensor: on the
floor, the other track lies between the sensor and the track, less than a body's width
from the line of sight, and near enough to the track that the line of sight, descending
from the sensor's height to the track's centroid, passes below the other's head. A
sensor on the ceiling looks over the people between (from straight above, over all of
them); one at chest height is blocked by anyone in between.
"""

from __future__ import annotations

import numpy as np

OCCLUSION_RADIUS_M = 0.3
"""Largest distance from a line of sight at which a person blocks it: about the sum of
two half shoulder widths (a man's biacromial breadth is about 0.40 m, a woman's 0.36 m;
ANSUR II anthropometric survey) less the half of a body a detector needs to see."""
HEAD_ABOVE_CENTROID_M = 0.75
"""How far the top of a standing person's head is above the centroid a detector reports:
the body's centre is at about 55 % of stature (anthropometric tables, e.g. Winter,
*Biomechanics and Motor Control of Human Movement*), 0.8 m below the head of a 1.75 m
adult; a little less for the points a sensor sees of a person, less for children."""
MIN_DETECTIONS = 30
"""Detections a sensor must have reported before its position is trusted."""
MIN_SPREAD_M2 = 0.25
"""Least variance (m^2) of its detections' positions along their narrowest direction:
detections along one line cannot fix a sensor's position across it."""


class _Normal:
    """Normal equations of one sensor's position problem.

    Rows ``(2x, 2y, -1)``: ``A^T A`` also holds the count of detections and the sums of
    their positions and of their outer products, so they are read from it.
    """

    def __init__(self) -> None:
        self.ata = np.zeros((3, 3))
        self.atb = np.zeros(3)
        self.view: tuple[np.ndarray, float] | None = None

    @property
    def n(self) -> int:
        """Detections added."""
        return round(float(self.ata[2, 2]))

    def add(self, xy: np.ndarray, distance: np.ndarray) -> None:
        a = np.column_stack([2.0 * xy, -np.ones(len(xy))])
        b = np.einsum("ij,ij->i", xy, xy) - distance**2
        self.ata += a.T @ a
        self.atb += a.T @ b
        self.view = None

    def solve(self) -> tuple[np.ndarray, float] | None:
        n = self.n
        if self.view is not None or n < MIN_DETECTIONS:
            return self.view
        mean = -0.5 * self.ata[0:2, 2] / n
        spread = 0.25 * self.ata[0:2, 0:2] / n - np.outer(mean, mean)
        if np.linalg.eigvalsh(spread)[0] < MIN_SPREAD_M2:
            return None
        sx, sy, c = np.linalg.solve(self.ata, self.atb)
        self.view = (np.array([sx, sy]), float(np.sqrt(max(c - sx * sx - sy * sy, 0.0))))
        return self.view


class Viewpoints:
    """Each sensor's position on the floor, from the ranges of its detections.

    Batches should be added once each (the caller counts them by sequence number, as
    the coverage map does), so a late-batch replay has nothing to undo.
    """

    def __init__(self) -> None:
        self._sensors: dict[str, _Normal] = {}

    def add(self, sensor_id: str, xy: np.ndarray, distance: np.ndarray) -> None:
        """Add a batch's detections ``xy (n, 2)`` and their ranges ``distance (n,)``."""
        ok = np.isfinite(distance) & (distance > 0)
        if ok.any():
            self._sensors.setdefault(sensor_id, _Normal()).add(xy[ok], distance[ok])

    def view(self, sensor_id: str) -> tuple[np.ndarray, float] | None:
        """The sensor's floor position ``(2,)`` and height above the people's centroids.

        ``None`` while they are not known.
        """
        sensor = self._sensors.get(sensor_id)
        return None if sensor is None else sensor.solve()


def hidden(
    viewpoint: np.ndarray,
    xy: np.ndarray,
    seen: np.ndarray,
    twin_m: float,
    height: float = 0.0,
    radius: float = OCCLUSION_RADIUS_M,
) -> np.ndarray:
    """Mask of the positions ``xy (n, 2)`` hidden behind the positions ``xy[seen]``.

    A position is hidden from the ``viewpoint`` (``height`` above the centroids) by a
    seen one nearer to it by more than ``radius`` (so two people side by side do not
    hide each other), less than ``radius`` from the line of sight and far enough along
    it that the line of sight is lower than the seen one's head there; unless a seen one
    is within ``twin_m`` of it: a track that close to a person the sensor sees may be a
    second track of that person (they are apart along the line of sight when the
    sensor's depth errs), which the sensor's misses should go on weakening. Whether a
    seen position is hidden does not depend on its having been seen.
    """
    seen = np.asarray(seen, dtype=np.intp)
    if len(xy) < 2 or not len(seen):
        return np.zeros(len(xy), dtype=bool)
    occluders = xy[seen]
    ray = xy - viewpoint
    rng = np.hypot(ray[:, 0], ray[:, 1])
    unit = ray / np.maximum(rng, 1e-9)[:, None]
    rel = occluders - viewpoint
    along = unit @ rel.T  # (n, m)
    across = np.abs(unit[:, 0:1] * rel[None, :, 1] - unit[:, 1:2] * rel[None, :, 0])
    blocks = (along > 0) & (along < rng[:, None] - radius) & (across < radius)
    if height > HEAD_ABOVE_CENTROID_M:
        # the line of sight is at height * (1 - along / range) above the centroids there
        blocks &= along > rng[:, None] * (1.0 - HEAD_ABOVE_CENTROID_M / height)
    apart = np.hypot(
        xy[:, None, 0] - occluders[None, :, 0], xy[:, None, 1] - occluders[None, :, 1]
    )
    twins = apart < twin_m
    twins[seen, np.arange(len(seen))] = False  # not its own twin
    return blocks.any(axis=1) & ~twins.any(axis=1)
