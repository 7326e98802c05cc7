"""Pairs of sensors: clock offsets, a RANSAC transform per pair, the pair graph, chaining.

Its single role is the coarse calibration, pair by pair, that the joint solve starts
from (Zhang et al., children behavior tracking, §2.2: the transform between two sensors
from one walking person's positions both see, by RANSAC over the correspondences):

* candidate clock offsets of a pair from the cross-correlation of the two sensors'
  walking-speed profiles (``|v(t)|`` does not depend on the unknown transform);
* at each candidate, a two-point RANSAC rigid transform over the time-matched
  detections (one sensor's detections against the other's smoothed trajectory; false
  positives fall out as outliers), refined by Kabsch on the inliers; the candidate with
  most inliers is kept;
* the graph of the pairs that overlap: a check that it connects every sensor over
  enough floor (errors name the separate groups, or the pairs walked too narrowly),
  then poses and offsets chained from the reference sensor along its maximum spanning
  tree (by inliers).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from openptrack_py.calibration.posegraph import connected_groups
from openptrack_py.calibration.walk_settings import WalkSettings
from openptrack_py.calibration.walk_tracks import Pose2D, _interp, _matches, _rot, _Walker
from openptrack_py.errors import CalibrationError

# ------------------------------------------------------------------ clocks and pairs


def _speed_profile(w: _Walker, grid: np.ndarray) -> np.ndarray:
    """Walking speed on ``grid`` (sensor clock), nan where the walker is not tracked."""
    _, vel, valid = _interp(w, grid)
    return np.where(valid, np.linalg.norm(vel, axis=1), np.nan)


def _lag_candidates(
    wi: _Walker, wj: _Walker, s: WalkSettings, extra: Sequence[float] = (0.0,)
) -> list[float]:
    """Clock offsets ``o_j - o_i`` worth trying: speed cross-correlation peaks and ``extra``.

    ``corr(L)`` is the Pearson correlation of ``|v_i(t)|`` and ``|v_j(t + L)|`` over the
    times both track the walker; its three highest local maxima are refined by a
    parabola through their neighbours.
    """
    step = s.speed_grid_s
    lo = min(wi.t[0], wj.t[0]) - s.max_clock_offset_s
    hi = max(wi.t[-1], wj.t[-1]) + s.max_clock_offset_s
    grid = np.arange(lo, hi, step)
    a = _speed_profile(wi, grid)
    b = _speed_profile(wj, grid)
    steps = round(s.max_clock_offset_s / step)
    need = int(5.0 / step)  # at least 5 s of common tracking
    corr = np.full(2 * steps + 1, np.nan)
    n = len(grid)
    for m, lag in enumerate(range(-steps, steps + 1)):
        x = a[max(0, -lag) : n - max(0, lag)]
        y = b[max(0, lag) : n - max(0, -lag)]
        both = np.isfinite(x) & np.isfinite(y)
        if both.sum() < need:
            continue
        x, y = x[both] - x[both].mean(), y[both] - y[both].mean()
        denom = math.sqrt(float(x @ x) * float(y @ y))
        if denom > 0:
            corr[m] = float(x @ y) / denom
    out = list(extra)
    filled = np.where(np.isfinite(corr), corr, -np.inf)
    peaks = [
        m
        for m in range(len(corr))
        if np.isfinite(corr[m])
        and (m == 0 or filled[m] >= filled[m - 1])
        and (m == len(corr) - 1 or filled[m] >= filled[m + 1])
    ]
    peaks.sort(key=lambda m: -filled[m])
    for m in peaks[:3]:
        shift = 0.0
        if 0 < m < len(corr) - 1 and np.isfinite(corr[m - 1]) and np.isfinite(corr[m + 1]):
            den = corr[m - 1] - 2 * corr[m] + corr[m + 1]
            if den < 0:
                shift = 0.5 * (corr[m - 1] - corr[m + 1]) / den
        lag = (m - steps + shift) * step
        if all(abs(lag - o) > 0.05 for o in out):
            out.append(lag)
    return out


def _kabsch(p: np.ndarray, q: np.ndarray) -> Pose2D:
    """The rigid transform ``A`` minimising ``sum |A(q) - p|^2``."""
    pc, qc = p.mean(axis=0), q.mean(axis=0)
    dp, dq = p - pc, q - qc
    theta = math.atan2(
        float(np.sum(dp[:, 1] * dq[:, 0] - dp[:, 0] * dq[:, 1])),
        float(np.sum(dp[:, 0] * dq[:, 0] + dp[:, 1] * dq[:, 1])),
    )
    t = pc - _rot(theta) @ qc
    return Pose2D(float(t[0]), float(t[1]), math.degrees(theta))


def _ransac(
    p: np.ndarray,
    q: np.ndarray,
    rng: np.random.Generator,
    s: WalkSettings,
    prior: Pose2D | None = None,
) -> tuple[Pose2D, np.ndarray]:
    """RANSAC rigid transform ``A`` with ``A(q) ≈ p``: two-point hypotheses, then refits."""
    n = len(p)
    thr = s.ransac_threshold_m
    if n < 3:
        return Pose2D(), np.zeros(n, dtype=bool)
    h = s.ransac_iterations
    a, b = rng.integers(0, n, (2, h))
    dp, dq = p[b] - p[a], q[b] - q[a]
    lp, lq = np.linalg.norm(dp, axis=1), np.linalg.norm(dq, axis=1)
    ok = (lq > 0.5) & (np.abs(lp - lq) < thr)
    theta = np.arctan2(dp[:, 1], dp[:, 0]) - np.arctan2(dq[:, 1], dq[:, 0])
    c, sn = np.cos(theta), np.sin(theta)
    mq = 0.5 * (q[a] + q[b])
    mp = 0.5 * (p[a] + p[b])
    tx = mp[:, 0] - (c * mq[:, 0] - sn * mq[:, 1])
    ty = mp[:, 1] - (sn * mq[:, 0] + c * mq[:, 1])
    models = np.column_stack([c, sn, tx, ty])[ok]
    if prior is not None:
        r = prior.rotation()
        models = np.vstack([models, [r[0, 0], r[1, 0], prior.x, prior.y]])
    if not len(models):
        return Pose2D(), np.zeros(n, dtype=bool)
    sub = rng.choice(n, min(n, 1500), replace=False)
    qs, ps = q[sub], p[sub]
    mx = models[:, None, 0] * qs[None, :, 0] - models[:, None, 1] * qs[None, :, 1]
    my = models[:, None, 1] * qs[None, :, 0] + models[:, None, 0] * qs[None, :, 1]
    dx = mx + models[:, None, 2] - ps[None, :, 0]
    dy = my + models[:, None, 3] - ps[None, :, 1]
    score = (dx * dx + dy * dy < thr * thr).sum(axis=1)
    best = models[int(np.argmax(score))]
    model = Pose2D(float(best[2]), float(best[3]), math.degrees(math.atan2(best[1], best[0])))
    inliers = np.linalg.norm(model.apply(q) - p, axis=1) < thr
    for _ in range(4):
        if inliers.sum() < 3:
            break
        model = _kabsch(p[inliers], q[inliers])
        again = np.linalg.norm(model.apply(q) - p, axis=1) < thr
        if np.array_equal(again, inliers):
            break
        inliers = again
    return model, inliers


def _extent(points: np.ndarray) -> tuple[float, float]:
    """Span (5th to 95th percentile) of points along their major and minor axes."""
    if len(points) < 3:
        return 0.0, 0.0
    centred = points - points.mean(axis=0)
    _, _, axes = np.linalg.svd(centred, full_matrices=False)
    proj = centred @ axes.T
    span = np.percentile(proj, 95, axis=0) - np.percentile(proj, 5, axis=0)
    return float(span[0]), float(span[1])


@dataclass(frozen=True, eq=False)
class _Pair:
    """The pairwise result for sensors ``i < j``: ``A`` maps ``j``'s floor into ``i``'s."""

    i: str
    j: str
    lag: float
    transform: Pose2D
    rows: np.ndarray  # i's samples matched against j
    inliers: np.ndarray  # mask over rows
    rows_back: np.ndarray  # j's samples matched against i
    inliers_back: np.ndarray
    extent: tuple[float, float]

    @property
    def count(self) -> int:
        return int(self.inliers.sum())


def _pair(wi: _Walker, wj: _Walker, s: WalkSettings, prior: tuple[Pose2D, float] | None) -> _Pair:
    """RANSAC the pair over the candidate clock offsets; keep the one with most inliers."""
    rng = np.random.default_rng([s.seed, *(ord(c) for c in wi.sensor + "|" + wj.sensor)])
    extra = [0.0] if prior is None else [prior[1], 0.0]
    best: tuple[int, float, Pose2D, np.ndarray, np.ndarray] | None = None
    for lag in _lag_candidates(wi, wj, s, extra):
        rows = _matches(wi, wj, lag)
        q, _, _ = _interp(wj, wi.t[rows] + lag)
        model, inliers = _ransac(wi.xy[rows], q, rng, s, None if prior is None else prior[0])
        if best is None or inliers.sum() > best[0]:
            best = (int(inliers.sum()), lag, model, rows, inliers)
    assert best is not None
    _, lag, model, rows, inliers = best
    q, _, _ = _interp(wj, wi.t[rows] + lag)
    extent = _extent(q[inliers])
    back = _matches(wj, wi, -lag)
    qb, _, _ = _interp(wi, wj.t[back] - lag)
    back_in = np.linalg.norm(model.apply(wj.xy[back]) - qb, axis=1) < s.ransac_threshold_m
    if inliers.sum() < s.min_pair_matches:
        back_in[:] = False
    return _Pair(wi.sensor, wj.sensor, lag, model, rows, inliers, back, back_in, extent)


# ----------------------------------------------------------------------- the graph


def _components(ids: Sequence[str], edges: Iterable[tuple[str, str]]) -> list[list[str]]:
    """Connected components, each in ``ids`` order, the components by first member."""
    return connected_groups(ids, dict.fromkeys(edges, 1), 1)


def _check_graph(ids: Sequence[str], pairs: Sequence[_Pair], s: WalkSettings) -> None:
    """Raise unless the sensors are connected by pairs that overlap over enough floor."""
    overlapping = [p for p in pairs if p.count >= s.min_pair_matches]
    groups = _components(ids, ((p.i, p.j) for p in overlapping))
    if len(groups) > 1:
        named = " | ".join("{" + ", ".join(g) + "}" for g in groups)
        raise CalibrationError(
            f"walk: the views of these groups of sensors never overlap during the walk: "
            f"{named}; each pair needs at least {s.min_pair_matches} detections of the "
            "walker at the same instant: walk where the groups' views meet, or add a sensor"
        )
    wide = [p for p in overlapping if _covers(p, s)]
    groups = _components(ids, ((p.i, p.j) for p in wide))
    if len(groups) > 1:
        where = {i: g for g, members in enumerate(groups) for i in members}
        narrow = [p for p in overlapping if where[p.i] != where[p.j]]
        lo, lo2 = s.min_extent_m
        named = "; ".join(f"{p.i}-{p.j}: {p.extent[0]:.2f} x {p.extent[1]:.2f} m" for p in narrow)
        raise CalibrationError(
            f"walk: the walk covers too little of the common view of {named} (need at "
            f"least {lo:.2f} x {lo2:.2f} m of matched positions): walk back and forth "
            "across the area these sensors share, not along a single line"
        )


def _covers(p: _Pair, s: WalkSettings) -> bool:
    return p.extent[0] >= s.min_extent_m[0] and p.extent[1] >= s.min_extent_m[1]


def _chain(
    ids: Sequence[str],
    pairs: Sequence[_Pair],
    reference: str,
    reference_pose: Pose2D,
    s: WalkSettings,
) -> tuple[dict[str, Pose2D], dict[str, float]]:
    """Poses and offsets along the maximum spanning tree (by inliers) from ``reference``."""
    usable = [p for p in pairs if p.count >= s.min_pair_matches and _covers(p, s)]
    poses = {reference: reference_pose}
    offsets = {reference: 0.0}
    while len(poses) < len(ids):
        best: _Pair | None = None
        for p in usable:
            if (p.i in poses) != (p.j in poses) and (best is None or p.count > best.count):
                best = p
        if best is None:  # _check_graph rules this out
            raise CalibrationError("walk: sensors not connected")
        if best.i in poses:
            poses[best.j] = poses[best.i].compose(best.transform)
            offsets[best.j] = offsets[best.i] + best.lag
        else:
            poses[best.i] = poses[best.j].compose(best.transform.inverse())
            offsets[best.i] = offsets[best.j] - best.lag
    return poses, offsets


def _all_pairs(
    walkers: Sequence[_Walker], s: WalkSettings, prior: np.ndarray | None
) -> list[_Pair]:
    out = []
    for a in range(len(walkers)):
        for b in range(a + 1, len(walkers)):
            hint = None
            if prior is not None:
                pa = Pose2D(prior[a, 0], prior[a, 1], math.degrees(prior[a, 2]))
                pb = Pose2D(prior[b, 0], prior[b, 1], math.degrees(prior[b, 2]))
                hint = (pa.inverse().compose(pb), float(prior[b, 3] - prior[a, 3]))
            out.append(_pair(walkers[a], walkers[b], s, hint))
    return out
