"""Each person on their own: trajectory, momentum, motion range, speed.

The childcare tracking paper (Zhang et al., §3.2) gives nursery teachers each child's
trajectory, its *momentum* (the length of the trajectory, growing over the class) and
its *motion range* (the bounding rectangle of the trajectory). :class:`PersonTally`
keeps these for one person as frames stream in, in memory that does not grow with the
recording. The trajectory is the positions averaged over ``smooth_s`` (a tracker's
jitter, above all while a person stands still, is not walking, and its outliers are not
places visited); on it: the path length on steps of at least ``step_s``, the bounding
rectangle, the convex hull (its vertices only), the speed on those steps, momentum every
``momentum_every_s`` and a trajectory for plots thinned to at most ``max_plot_points``;
and a density-based area (the smallest set of ``cell_m`` cells holding
``density_share`` of the person's time: where they really were, not the corners they
once crossed).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from openptrack_py.geometry import polygon_area

__all__ = ["PersonSummary", "PersonTally", "ThinnedSeries", "convex_hull", "polygon_area"]

TILE = 16
"""Cells per side of the tiles a person's time per cell is kept in (4 m of 0.25 m cells):
a few kilobytes each, only where the person went."""
SPEED_BINS_MPS = (0.0, 0.2, 0.5, 1.0, 1.5, 2.0, 3.0, math.inf)
"""Edges of the speed histogram (standing, shuffling, walking slowly, walking, fast...)."""


class ThinnedSeries:
    """At most ``capacity`` rows of a long series, evenly spread over all of it.

    Every ``every``-th row offered is kept; when the rows fill ``capacity``, every other
    one is dropped and ``every`` doubles. Rows live in one float array grown by doubling,
    so an hour of a person's trajectory takes at most ``capacity`` rows of 8-byte numbers
    (not a Python tuple per point).

    Parameters
    ----------
    capacity : int
        Most rows kept (at least 2).
    width : int
        Numbers per row.
    """

    def __init__(self, capacity: int, width: int) -> None:
        self.capacity = max(2, capacity)
        self.every = 1
        self._rows = np.empty((min(16, self.capacity), width))
        self._n = 0
        self._offered = 0

    def offer(self, *row: float) -> None:
        """The next row of the series (kept or not)."""
        self._offered += 1
        if (self._offered - 1) % self.every:
            return
        if self._n == self.capacity:  # full: keep every other row, keep half as often
            kept = self._rows[0 : self._n : 2].copy()
            self._n = len(kept)
            self._rows[: self._n] = kept
            self.every *= 2
            if (self._offered - 1) % self.every:
                return
        if self._n == len(self._rows):
            grown = np.empty((min(2 * len(self._rows), self.capacity), self._rows.shape[1]))
            grown[: self._n] = self._rows[: self._n]
            self._rows = grown
        self._rows[self._n] = row
        self._n += 1

    def array(self) -> np.ndarray:
        """The rows kept, in order (a copy)."""
        return self._rows[: self._n].copy()


def convex_hull(points: np.ndarray) -> np.ndarray:
    """The convex hull of ``(n, 2)`` points, counter-clockwise (Andrew's monotone chain)."""
    pts = np.unique(np.asarray(points, dtype=float).reshape(-1, 2), axis=0)
    if len(pts) < 3:
        return pts

    def half(seq: np.ndarray) -> list[np.ndarray]:
        out: list[np.ndarray] = []
        for p in seq:
            while len(out) >= 2:
                a, b = out[-2], out[-1]
                if (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) > 0:
                    break
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


@dataclass
class PersonSummary:
    """One person's figures over a recording.

    Parameters
    ----------
    key : int
        The identity (``stable_id``, else the track id, or a ground-truth id).
    name : str or None
        The roster's name for them.
    first_t, last_t : float
        First and last time seen, UNIX seconds.
    seen_s : float
        Time seen, seconds.
    length_m : float
        Trajectory length (momentum at the end), metres.
    bbox : (float, float, float, float)
        Bounding rectangle ``(x_min, y_min, x_max, y_max)``: the paper's motion range.
    bbox_area_m2, hull_area_m2, density_area_m2 : float
        Areas of the rectangle, of the convex hull, and of the cells holding
        ``density_share`` of the time.
    mean_speed_mps, max_speed_mps : float
        Over the steps measured.
    speed_histogram_s : list of float
        Seconds spent in each speed band (:data:`SPEED_BINS_MPS`).
    momentum : list of (float, float)
        ``(t, length so far)`` every ``momentum_every_s``.
    hull : ndarray
        Convex hull vertices.
    path : ndarray
        ``(n, 3)`` of ``t, x, y``, thinned for plots.
    """

    key: int
    name: str | None
    first_t: float
    last_t: float
    seen_s: float
    length_m: float
    bbox: tuple[float, float, float, float]
    bbox_area_m2: float
    hull_area_m2: float
    density_area_m2: float
    mean_speed_mps: float
    max_speed_mps: float
    speed_histogram_s: list[float]
    momentum: list[tuple[float, float]]
    hull: np.ndarray
    path: np.ndarray

    def row(self) -> dict[str, object]:
        """The figures as a table row."""
        return {
            "person": self.key,
            "name": self.name or "",
            "seen_s": round(self.seen_s, 1),
            "length_m": round(self.length_m, 2),
            "bbox_area_m2": round(self.bbox_area_m2, 2),
            "hull_area_m2": round(self.hull_area_m2, 2),
            "density_area_m2": round(self.density_area_m2, 2),
            "mean_speed_mps": round(self.mean_speed_mps, 3),
            "max_speed_mps": round(self.max_speed_mps, 3),
        }


@dataclass
class PersonTally:
    """Accumulates one person's figures, frame by frame (see the module).

    Parameters
    ----------
    key : int
        The person.
    step_s : float
        Shortest step the path length and speed are measured on.
    smooth_s : float
        Positions are averaged over this long before the path is measured.
    max_gap_s : float
        A longer gap between two sightings starts a new piece of path.
    cell_m : float
        Cell of the density area.
    density_share : float
        Share of the person's time the density area holds.
    momentum_every_s : float
        Spacing of the momentum series (doubled whenever it would pass ``max_plot_points``).
    max_plot_points : int
        Most points kept of the path and of the momentum series for plots.
    """

    key: int
    step_s: float = 1.0
    smooth_s: float = 1.0
    max_gap_s: float = 1.0
    cell_m: float = 0.25
    density_share: float = 0.9
    momentum_every_s: float = 5.0
    max_plot_points: int = 1000
    name: str | None = None
    first_t: float | None = None
    last_t: float | None = None
    seen_s: float = 0.0
    length_m: float = 0.0
    moving_s: float = 0.0
    max_speed_mps: float = 0.0
    _anchor: tuple[float, float, float] | None = None  # t, x, y of the last step's end
    _recent: deque[tuple[float, float, float]] = field(default_factory=deque)
    _latest: tuple[float, float, float] | None = None
    _lo: list[float] = field(default_factory=lambda: [math.inf, math.inf])
    _hi: list[float] = field(default_factory=lambda: [-math.inf, -math.inf])
    _hull: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    _pending: list[tuple[float, float]] = field(default_factory=list)
    _tiles: dict[tuple[int, int], np.ndarray] = field(default_factory=dict)
    _speeds: np.ndarray = field(default_factory=lambda: np.zeros(len(SPEED_BINS_MPS) - 1))
    _momentum: ThinnedSeries = field(init=False)
    _path: ThinnedSeries = field(init=False)
    _momentum_t: float = -math.inf

    def __post_init__(self) -> None:
        self._momentum = ThinnedSeries(self.max_plot_points, 2)
        self._path = ThinnedSeries(self.max_plot_points, 3)

    def add(self, t: float, x: float, y: float, dt: float, name: str | None = None) -> None:
        """The person is at ``(x, y)`` at ``t``, for ``dt`` seconds of the recording."""
        if name:
            self.name = name
        if self.first_t is None:
            self.first_t = t
        gap = t - self.last_t if self.last_t is not None else math.inf
        self.last_t = t
        self.seen_s += dt
        i, j = math.floor(x / self.cell_m), math.floor(y / self.cell_m)
        tile = self._tiles.get((i // TILE, j // TILE))
        if tile is None:
            tile = self._tiles[(i // TILE, j // TILE)] = np.zeros((TILE, TILE), np.float32)
        tile[i % TILE, j % TILE] += dt
        if gap > self.max_gap_s:
            self._recent.clear()
        self._recent.append((t, x, y))
        while self._recent[0][0] < t - self.smooth_s:
            self._recent.popleft()
        mean = np.mean(np.array(self._recent)[:, 1:], axis=0)
        x, y = float(mean[0]), float(mean[1])  # the trajectory: the averaged positions
        self._latest = (t, x, y)
        self._lo = [min(self._lo[0], x), min(self._lo[1], y)]
        self._hi = [max(self._hi[0], x), max(self._hi[1], y)]
        self._pending.append((x, y))
        if len(self._pending) >= 256:
            self._fold_hull()
        self._step(t, x, y, gap)
        if t - self._momentum_t >= self.momentum_every_s:
            self._momentum_t = t
            self._momentum.offer(t, self.length_m)
        self._path.offer(t, x, y)

    def _step(self, t: float, x: float, y: float, gap: float) -> None:
        if self._anchor is None or gap > self.max_gap_s:
            self._anchor = (t, x, y)
            return
        t0, x0, y0 = self._anchor
        elapsed = t - t0
        if elapsed < self.step_s:
            return
        dist = math.hypot(x - x0, y - y0)
        self.length_m += dist
        speed = dist / elapsed
        self.max_speed_mps = max(self.max_speed_mps, speed)
        self.moving_s += elapsed
        band = int(np.searchsorted(SPEED_BINS_MPS, speed, side="right")) - 1
        self._speeds[min(band, len(self._speeds) - 1)] += elapsed
        self._anchor = (t, x, y)

    def _fold_hull(self) -> None:
        if self._pending:
            self._hull = convex_hull(np.vstack([self._hull, np.array(self._pending)]))
            self._pending = []

    def _density_area(self) -> float:
        if not self._tiles:
            return 0.0
        times = np.concatenate([t.ravel() for t in self._tiles.values()]).astype(float)
        times = np.sort(times[times > 0])[::-1]
        if not len(times) or times.sum() <= 0:
            return 0.0
        needed = int(np.searchsorted(np.cumsum(times), self.density_share * times.sum()) + 1)
        return min(needed, len(times)) * self.cell_m**2

    def _length_to_latest(self) -> float:
        """The path length with the last, unfinished step."""
        if self._anchor is None or self._latest is None or self._latest[0] <= self._anchor[0]:
            return self.length_m
        return self.length_m + math.hypot(
            self._latest[1] - self._anchor[1], self._latest[2] - self._anchor[2]
        )

    def summary(self) -> PersonSummary:
        """The figures so far."""
        self._fold_hull()
        length = self._length_to_latest()
        lo, hi = self._lo, self._hi
        bbox = (lo[0], lo[1], hi[0], hi[1])
        momentum = [(float(a), float(b)) for a, b in self._momentum.array()]
        if self.last_t is not None and (not momentum or momentum[-1][0] < self.last_t):
            momentum.append((self.last_t, length))
        return PersonSummary(
            key=self.key,
            name=self.name,
            first_t=self.first_t or 0.0,
            last_t=self.last_t or 0.0,
            seen_s=self.seen_s,
            length_m=length,
            bbox=bbox,
            bbox_area_m2=max(hi[0] - lo[0], 0.0) * max(hi[1] - lo[1], 0.0),
            hull_area_m2=polygon_area(self._hull),
            density_area_m2=self._density_area(),
            mean_speed_mps=self.length_m / self.moving_s if self.moving_s > 0 else 0.0,
            max_speed_mps=self.max_speed_mps,
            speed_histogram_s=[round(float(v), 3) for v in self._speeds],
            momentum=momentum,
            hull=self._hull.copy(),
            path=self._path.array(),
        )
