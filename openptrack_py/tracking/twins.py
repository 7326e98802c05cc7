"""A calibration error no shared track reveals, learned from the rigid map people agree on.

A sensor's alignment (:mod:`~openptrack_py.tracking.alignment`) is learned from tracks
that two sensors feed. A calibration off by more than an association gate (the
OpenPTrack paper reports 5-20 cm and 1-3 degrees before refinement; at 6 m, 3 degrees
alone is 0.3 m) leaves no such track: each sensor keeps its own track of every person,
a steady few tens of centimetres from the others' (*twins*), and nothing is learned.
Such a sensor is recognised by its *share*: of its tracks at places other sensors see,
how many others feed too (about all of them for a calibrated sensor, under half for
one whose every person has a twin; the sensor model keeps it).

Two confirmed tracks, one fed by such a sensor alone and the other by other sensors,
walking together at a steady separation, are either one person seen through two
calibrations or two people walking together; one such pair cannot tell which. Several
can: a calibration error is one rigid map of the floor for every person the sensors
see, while the offsets between people who walk together point every which way.
:class:`TwinAligner` keeps the last seconds of such pairs for every pair of sensors (or
sensor and group of sensors), finds by RANSAC (Fischler and Bolles, 1981) the rigid map
most of them agree on, and accepts it only where at least ``min_people`` distinct pairs
of tracks agree within ``tolerance_m``, each for most of its samples, and the map is no
larger than the calibration error believed possible. The samples that agree then
teach the sensors' alignments to meet half-way; their detections of each person
coincide, and the merger folds the twins together.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from openptrack_py.tracking.alignment import rigid_fit, rotation
from openptrack_py.tracking.state import TrackTable

# columns of TwinAligner.rows
_T, _SA, _SB, _IA, _IB, _AX, _AY, _BX, _BY = range(9)


@dataclass(frozen=True)
class TwinLesson:
    """Pairs of positions two sensors' twins agree on, to teach both alignments.

    Parameters
    ----------
    sensors_a : tuple of int
        The sensors that fed the ``a`` tracks (indices into the tracker's sensor order).
    sensor_b : int
        The one sensor that fed the ``b`` tracks.
    a, b : ndarray
        ``(k, 2)`` where the ``a`` and the ``b`` tracks were (the fused frame).
    """

    sensors_a: tuple[int, ...]
    sensor_b: int
    a: np.ndarray
    b: np.ndarray


def _pair_keys(rows: np.ndarray) -> np.ndarray:
    """One number per pair of track ids of ``rows``."""
    return rows[:, _IA] * 1e9 + rows[:, _IB]


@dataclass
class TwinAligner:
    """Collects twin pairs of tracks and finds the rigid map several people agree on.

    Parameters
    ----------
    max_shift_m : float
        Largest shift between two sensors' frames (where their twins are) believed possible.
    max_rotation_deg : float
        Largest rotation between two sensors' frames.
    tolerance_m : float
        How close a pair's positions must come under the map to agree with it.
    min_people : int
        Distinct pairs of tracks that must agree.
    steady_s : float
        How long a pair must have walked together at a steady separation.
    steady_sd_m : float
        Largest standard deviation of the separation over ``steady_s`` (both axes).
    min_travel_m : float
        How far a pair must have moved over ``steady_s`` (people standing still beside
        each other say nothing of a calibration).
    window_s : float
        Seconds of pairs kept.
    sample_every_s : float
        Time between two samples.
    draws : int
        RANSAC hypotheses per pair of sensors and look.
    """

    max_shift_m: float = 1.5
    max_rotation_deg: float = 10.0
    tolerance_m: float = 0.15
    min_people: int = 2
    steady_s: float = 2.0
    steady_sd_m: float = 0.15
    min_travel_m: float = 0.5
    window_s: float = 10.0
    sample_every_s: float = 0.25
    draws: int = 64
    rows: np.ndarray = field(default_factory=lambda: np.zeros((0, 9)))
    last_sample: float = -math.inf

    def copy(self) -> TwinAligner:
        """An independent copy."""
        return replace(self, rows=self.rows.copy())

    def due(self, t: float) -> bool:
        """Whether a look is due at ``t`` (one every ``sample_every_s``)."""
        return t - self.last_sample >= self.sample_every_s

    def observe(self, tb: TrackTable, t: float, unshared: set[int]) -> list[TwinLesson]:
        """Sample the table's twin pairs at ``t``; return the lessons of any map agreed on.

        ``unshared``: the sensors (by index) whose share is low; only they are taught,
        against one other such sensor or a group of sensors.
        """
        if not self.due(t):
            return []
        self.last_sample = t
        self.rows = self.rows[self.rows[:, _T] > t - self.window_s]
        if not unshared:
            return []
        self._sample(tb, t, unshared)
        lessons = []
        for sa, sb in np.unique(self.rows[:, [_SA, _SB]].astype(np.int64), axis=0).tolist():
            mine = (self.rows[:, _SA] == sa) & (self.rows[:, _SB] == sb)
            lesson = self._agree(self.rows[mine], t)
            if lesson is not None:
                group = tuple(k for k in range(64) if sa >> k & 1)
                lessons.append(TwinLesson(group, sb, lesson[:, 0:2], lesson[:, 2:4]))
                self.rows = self.rows[~mine]  # the alignments change: start afresh
        return lessons

    def _sample(self, tb: TrackTable, t: float, unshared: set[int]) -> None:
        """Remember the table's twin pairs now.

        The ``b`` track is fed by one unshared sensor alone, the ``a`` track by one other
        unshared sensor or by two or more others.
        """
        recent = t - tb.sensor_hit_t < self.steady_s  # (n, slots): who fed each track
        fed = recent.sum(axis=1)
        idx = np.flatnonzero(
            tb.confirmed
            & (fed >= 1)
            & (t - tb.first_seen >= 1.0)
            & (t - tb.last_seen <= self.sample_every_s)
        )
        if len(idx) < 2:
            return
        masks = recent[idx] @ (1 << np.arange(recent.shape[1], dtype=np.int64))
        low = np.zeros(recent.shape[1], dtype=bool)
        low[[k for k in unshared if k < len(low)]] = True
        sole = (fed[idx] == 1) & low[recent[idx].argmax(axis=1)]
        single_low = sole | (fed[idx] > 1)  # an ``a`` side: low, or a group
        xy = tb.x[idx, 0:2]
        gap = np.linalg.norm(xy[:, None] - xy[None], axis=2)
        i, j = np.nonzero(
            (gap < self.max_shift_m)
            & ((masks[:, None] & masks[None, :]) == 0)
            & sole[None, :]
            & single_low[:, None]
            & (~sole[:, None] | (masks[:, None] < masks[None, :]))
        )
        if not len(i):
            return
        new = np.column_stack([
            np.full(len(i), t), masks[i], np.log2(masks[j]).round(), tb.ids[idx[i]],
            tb.ids[idx[j]], xy[i], xy[j],
        ])  # fmt: skip
        self.rows = np.concatenate([self.rows, new])

    def _steady(self, rows: np.ndarray) -> np.ndarray:
        """Mask of the rows whose pair walked together steadily for ``steady_s`` or more."""
        keep = np.zeros(len(rows), dtype=bool)
        pairs = _pair_keys(rows)
        need = 0.75 * self.steady_s / self.sample_every_s
        for key in np.unique(pairs):
            mine = pairs == key
            if mine.sum() < need:
                continue
            sep = rows[mine, _AX : _AY + 1] - rows[mine, _BX : _BY + 1]
            path = rows[mine, _AX : _AY + 1]
            if (
                math.sqrt(float(sep.var(axis=0).sum())) <= self.steady_sd_m
                and float(np.linalg.norm(path[-1] - path[0])) >= self.min_travel_m
            ):
                keep |= mine
        return keep

    def _agree(self, rows: np.ndarray, t: float) -> np.ndarray | None:
        """``(k, 4)`` positions ``a, b`` of the samples that agree on one map, or None."""
        rows = rows[self._steady(rows)]
        pairs = _pair_keys(rows)
        if len(np.unique(pairs)) < self.min_people:
            return None
        a, b = rows[:, _AX : _AY + 1], rows[:, _BX : _BY + 1]
        rng = np.random.default_rng(int(t * 1000) & 0xFFFFFFFF)  # a replay draws the same
        best, best_count = None, 0
        for _ in range(self.draws):
            p, q = rng.choice(len(rows), 2, replace=False)
            if pairs[p] == pairs[q] or np.linalg.norm(b[p] - b[q]) < 1.0:
                continue
            theta, shift = rigid_fit(b[[p, q]], a[[p, q]])
            inliers = self._agreeing(pairs, self._inliers(a, b, theta, shift))
            count = self._people(rows[inliers])
            if count > best_count:
                best, best_count = inliers, count
        if best is None or best_count < self.min_people:
            return None
        theta, shift = rigid_fit(b[best], a[best])
        best = self._agreeing(pairs, self._inliers(a, b, theta, shift))
        if self._people(rows[best]) < self.min_people:
            return None
        return np.column_stack([a[best], b[best]])

    @staticmethod
    def _agreeing(pairs: np.ndarray, inliers: np.ndarray) -> np.ndarray:
        """The inliers of the pairs (keys per sample) most of whose samples are inliers."""
        keep = inliers.copy()
        for key in np.unique(pairs[inliers]):
            mine = pairs == key
            if inliers[mine].mean() < 0.5:
                keep &= ~mine
        return keep

    def _inliers(
        self, a: np.ndarray, b: np.ndarray, theta: float, shift: np.ndarray
    ) -> np.ndarray:
        """Samples the map takes within tolerance, if the map is one believed possible."""
        if abs(theta) > math.radians(self.max_rotation_deg):
            return np.zeros(len(a), dtype=bool)
        mapped = b @ rotation(theta).T + shift
        if float(np.linalg.norm((mapped - b).mean(axis=0))) > self.max_shift_m:
            return np.zeros(len(a), dtype=bool)
        return np.linalg.norm(mapped - a, axis=1) <= self.tolerance_m

    @staticmethod
    def _people(rows: np.ndarray) -> int:
        """Distinct pairs of tracks among ``rows``, counting each track once."""
        seen_a: set[float] = set()
        seen_b: set[float] = set()
        count = 0
        for ia, ib in sorted({(float(r[_IA]), float(r[_IB])) for r in rows}):
            if ia not in seen_a and ib not in seen_b:
                seen_a.add(ia)
                seen_b.add(ib)
                count += 1
        return count
