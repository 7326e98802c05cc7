"""Two people together: their relative distance over time.

The childcare tracking paper (Zhang et al., §3.2.3, Fig. 9) gives teachers the distance
between two people over a class, with its mean and standard deviation (teacher to child:
who relies on the teacher; child to child: who plays together). :class:`PairTally`
keeps, for every pair seen at the same time, the running mean and variance (Welford),
the closest approach and the time together, in memory that does not grow with the
recording; the distance itself is kept as a series (one value per ``series_every_s``)
only while at most ``max_series_people`` people have been seen, for plots. A frame with
more than ``max_people`` people (a crowd, where every pair's distance means nothing and
their number grows as the square) is not used for pairs, and counted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["PairSummary", "PairTally"]


@dataclass
class PairSummary:
    """Two people's relative distance over a recording.

    Parameters
    ----------
    a, b : int
        The two people (``a < b``).
    together_s : float
        Time both were seen at once, seconds.
    mean_m, std_m, min_m : float
        Mean, standard deviation and least of their distance, metres.
    series : ndarray
        ``(n, 2)`` of ``t, distance`` (empty when not kept).
    """

    a: int
    b: int
    together_s: float
    mean_m: float
    std_m: float
    min_m: float
    series: np.ndarray

    def row(self, names: dict[int, str] | None = None) -> dict[str, object]:
        """The figures as a table row."""
        names = names or {}
        return {
            "a": self.a,
            "b": self.b,
            "a_name": names.get(self.a, ""),
            "b_name": names.get(self.b, ""),
            "together_s": round(self.together_s, 1),
            "mean_m": round(self.mean_m, 3),
            "std_m": round(self.std_m, 3),
            "min_m": round(self.min_m, 3),
        }


@dataclass
class _Pair:
    weight: float = 0.0
    mean: float = 0.0
    m2: float = 0.0
    least: float = math.inf
    series: list[tuple[float, float]] = field(default_factory=list)


@dataclass
class PairTally:
    """Accumulates every pair's distance, frame by frame (see the module).

    Parameters
    ----------
    series_every_s : float
        Spacing of the kept distance series.
    max_series_people : int
        Series are kept only while no more people than this have been seen.
    max_people : int
        Frames with more people than this are skipped (``skipped_frames``).
    """

    series_every_s: float = 1.0
    max_series_people: int = 30
    max_people: int = 40
    skipped_frames: int = 0
    _pairs: dict[tuple[int, int], _Pair] = field(default_factory=dict)
    _people: set[int] = field(default_factory=set)
    _next_series_t: float = -math.inf

    def add(self, t: float, positions: dict[int, tuple[float, float]], dt: float) -> None:
        """Everyone's position at ``t``, for ``dt`` seconds of the recording."""
        keys = sorted(positions)
        if len(keys) > self.max_people:
            self.skipped_frames += 1
            return
        self._people.update(keys)
        if len(keys) < 2 or dt <= 0:
            return
        xy = np.array([positions[k] for k in keys], dtype=float)
        ii, jj = np.triu_indices(len(keys), 1)
        dist = np.hypot(*(xy[ii] - xy[jj]).T)
        keep_series = len(self._people) <= self.max_series_people and t >= self._next_series_t
        if keep_series:
            self._next_series_t = t + self.series_every_s
        for i, j, d in zip(ii.tolist(), jj.tolist(), dist.tolist(), strict=True):
            pair = self._pairs.get((keys[i], keys[j]))
            if pair is None:
                pair = self._pairs[(keys[i], keys[j])] = _Pair()
            # weighted Welford (West, 1979): each frame counts for its duration
            pair.weight += dt
            delta = d - pair.mean
            pair.mean += delta * dt / pair.weight
            pair.m2 += dt * delta * (d - pair.mean)
            pair.least = min(pair.least, d)
            if keep_series:
                pair.series.append((t, d))
        if len(self._people) > self.max_series_people:
            for pair in self._pairs.values():
                pair.series.clear()

    def summaries(self) -> dict[tuple[int, int], PairSummary]:
        """Every pair's figures so far."""
        out = {}
        for (a, b), p in self._pairs.items():
            std = math.sqrt(p.m2 / p.weight) if p.weight > 0 else 0.0
            series = np.array(p.series, dtype=float).reshape(-1, 2)
            out[(a, b)] = PairSummary(a, b, p.weight, p.mean, std, p.least, series)
        return out
