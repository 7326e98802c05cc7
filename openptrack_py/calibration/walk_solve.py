"""The joint solve: one robust least squares over every sensor's floor pose and clock.

Its single role is the fit shared by both procedures of
:mod:`openptrack_py.calibration.walk` (Munaro et al., OpenPTrack, §4.3, refines the
sensors' poses from a walk by least squares over their matched detections; here the
clock offsets are solved with them). One ``scipy.optimize.least_squares`` (soft-L1
loss, analytic Jacobian) over every sensor's ``(x, y, yaw, clock offset)`` and every
time-matched pair of detections of every overlapping pair of sensors, in both
directions: ``R_i p_i(t) + T_i - R_j q_j(t - o_i + o_j) - T_j``, where ``q_j`` is sensor
``j``'s smoothed trajectory interpolated at the stamp of the same true time. Matches are
re-made and outliers re-gated with the solved offsets and poses, and solved again.

Also here: the two cross-validation folds (alternating blocks of true time) a solve may
be restricted to, and the mean anchor, which moves a solved network as one rigid body
(and shifts its clocks) so that the walk stays where the current calibration put it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from openptrack_py.calibration.walk_pairs import _kabsch, _Pair
from openptrack_py.calibration.walk_settings import WalkSettings
from openptrack_py.calibration.walk_tracks import Pose2D, _interp, _matches, _rot, _Walker

# ------------------------------------------------------------------- joint solve


@dataclass(frozen=True, eq=False)
class _Block:
    """Time-matched detections: sensor ``i``'s samples ``rows`` against ``j``'s trajectory."""

    i: int
    j: int
    rows: np.ndarray
    p: np.ndarray
    t: np.ndarray
    pair: int


def _residuals(
    blocks: Sequence[_Block],
    walkers: Sequence[_Walker],
    state: np.ndarray,
    *,
    raw: bool = False,
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per block, the world residuals ``(k, 2)`` and their validity.

    ``state`` holds per sensor ``(x, y, yaw_rad, offset)``.
    """
    out, valid = [], []
    for b in blocks:
        xi, yi, thi, oi = state[b.i]
        xj, yj, thj, oj = state[b.j]
        q, _, ok = _interp(walkers[b.j], b.t - oi + oj, raw=raw)
        r = b.p @ _rot(thi).T + (xi, yi) - q @ _rot(thj).T - (xj, yj)
        out.append(r)
        valid.append(ok)
    return out, valid


class _Problem:
    """The joint least squares over the free parameters of every sensor."""

    def __init__(
        self,
        walkers: Sequence[_Walker],
        blocks: Sequence[_Block],
        start: np.ndarray,
        free_pose: Sequence[bool],
        free_offset: Sequence[bool],
    ) -> None:
        self.walkers = walkers
        self.blocks = blocks
        self.start = start.copy()
        self.pose_col: dict[int, int] = {}
        self.off_col: dict[int, int] = {}
        n = 0
        for k, free in enumerate(free_pose):
            if free:
                self.pose_col[k] = n
                n += 3
        for k, free in enumerate(free_offset):
            if free:
                self.off_col[k] = n
                n += 1
        self.size = n
        self.rows = 2 * sum(len(b.rows) for b in blocks)

    def x0(self) -> np.ndarray:
        x = np.zeros(self.size)
        for k, c in self.pose_col.items():
            x[c : c + 3] = self.start[k, :3]
        for k, c in self.off_col.items():
            x[c] = self.start[k, 3]
        return x

    def state(self, x: np.ndarray) -> np.ndarray:
        st = self.start.copy()
        for k, c in self.pose_col.items():
            st[k, :3] = x[c : c + 3]
        for k, c in self.off_col.items():
            st[k, 3] = x[c]
        return st

    def fun(self, x: np.ndarray) -> np.ndarray:
        res, _ = _residuals(self.blocks, self.walkers, self.state(x))
        return np.concatenate([r.ravel() for r in res]) if res else np.zeros(0)

    def jac(self, x: np.ndarray) -> np.ndarray:
        st = self.state(x)
        out = np.zeros((self.rows, self.size))
        row = 0
        for b in self.blocks:
            k = len(b.rows)
            _, thi, oi = st[b.i, :2], st[b.i, 2], st[b.i, 3]
            thj, oj = st[b.j, 2], st[b.j, 3]
            q, v, _ = _interp(self.walkers[b.j], b.t - oi + oj)
            rj = _rot(thj)
            ci, si = math.cos(thi), math.sin(thi)
            cj, sj = math.cos(thj), math.sin(thj)
            dthi = np.column_stack(
                [-si * b.p[:, 0] - ci * b.p[:, 1], ci * b.p[:, 0] - si * b.p[:, 1]]
            )
            dthj = -np.column_stack([-sj * q[:, 0] - cj * q[:, 1], cj * q[:, 0] - sj * q[:, 1]])
            rv = v @ rj.T  # d r / d o_i = +R_j v ; d r / d o_j = -R_j v
            block = out[row : row + 2 * k]
            if b.i in self.pose_col:
                c = self.pose_col[b.i]
                block[0::2, c] = 1.0
                block[1::2, c + 1] = 1.0
                block[0::2, c + 2] = dthi[:, 0]
                block[1::2, c + 2] = dthi[:, 1]
            if b.j in self.pose_col:
                c = self.pose_col[b.j]
                block[0::2, c] = -1.0
                block[1::2, c + 1] = -1.0
                block[0::2, c + 2] = dthj[:, 0]
                block[1::2, c + 2] = dthj[:, 1]
            if b.i in self.off_col:
                c = self.off_col[b.i]
                block[0::2, c] = rv[:, 0]
                block[1::2, c] = rv[:, 1]
            if b.j in self.off_col:
                c = self.off_col[b.j]
                block[0::2, c] = -rv[:, 0]
                block[1::2, c] = -rv[:, 1]
            row += 2 * k
        return out


def _blocks_from_pairs(
    walkers: Sequence[_Walker], index: Mapping[str, int], pairs: Sequence[_Pair]
) -> list[_Block]:
    """The RANSAC inliers of every overlapping pair, both directions."""
    out = []
    for n, p in enumerate(pairs):
        i, j = index[p.i], index[p.j]
        for a, rows in ((i, p.rows[p.inliers]), (j, p.rows_back[p.inliers_back])):
            if len(rows):
                w = walkers[a]
                out.append(_Block(a, j if a == i else i, rows, w.xy[rows], w.t[rows], n))
    return out


def _regate(
    walkers: Sequence[_Walker],
    pairs: Sequence[_Pair],
    index: Mapping[str, int],
    state: np.ndarray,
    s: WalkSettings,
) -> list[_Block]:
    """Every time-matched detection of the overlapping pairs, gated by the current fit."""
    blocks = []
    for n, p in enumerate(pairs):
        i, j = index[p.i], index[p.j]
        for a, b in ((i, j), (j, i)):
            wa, wb = walkers[a], walkers[b]
            lag = state[b, 3] - state[a, 3]
            rows = _matches(wa, wb, lag)
            blocks.append(_Block(a, b, rows, wa.xy[rows], wa.t[rows], n))
    res, _ = _residuals(blocks, walkers, state)
    dist = np.concatenate([np.linalg.norm(r, axis=1) for r in res]) if res else np.zeros(0)
    gate = float(np.clip(3.0 * np.median(dist), 0.2, s.max_gate_m)) if len(dist) else 0.0
    out = []
    for b, r in zip(blocks, res, strict=True):
        keep = np.linalg.norm(r, axis=1) < gate
        if keep.sum():
            out.append(_Block(b.i, b.j, b.rows[keep], b.p[keep], b.t[keep], b.pair))
    return out


def _solve(
    walkers: Sequence[_Walker],
    pairs: Sequence[_Pair],
    index: Mapping[str, int],
    start: np.ndarray,
    free_pose: Sequence[bool],
    free_offset: Sequence[bool],
    s: WalkSettings,
    fold: int | None = None,
) -> tuple[np.ndarray, list[_Block]]:
    """Joint robust least squares; re-match and re-gate; repeat ``solve_rounds`` times.

    ``fold``: use only the matches of that cross-validation fold.
    """
    overlapping = [p for p in pairs if p.count >= s.min_pair_matches]
    blocks = _blocks_from_pairs(walkers, index, overlapping)
    # keep the pair numbering of ``pairs`` for the reports
    number = {id(p): n for n, p in enumerate(pairs)}
    blocks = [_Block(b.i, b.j, b.rows, b.p, b.t, number[id(overlapping[b.pair])]) for b in blocks]
    state = start.copy()
    blocks = _in_fold(blocks, state, fold, s)
    for round_ in range(max(1, s.solve_rounds)):
        problem = _Problem(walkers, blocks, state, free_pose, free_offset)
        if problem.size and problem.rows > problem.size:
            fit = least_squares(
                problem.fun,
                problem.x0(),
                jac=problem.jac,
                loss=s.loss,
                f_scale=s.loss_scale_m,
                x_scale="jac",
                max_nfev=100,
            )
            state = problem.state(fit.x)
        if round_ < s.solve_rounds - 1:
            blocks = _regate(walkers, pairs, index, state, s)
            blocks = [b for b in blocks if pairs[b.pair].count >= s.min_pair_matches]
            blocks = _in_fold(blocks, state, fold, s)
    return state, blocks


def _in_fold(
    blocks: Sequence[_Block], state: np.ndarray, fold: int | None, s: WalkSettings
) -> list[_Block]:
    """The blocks' matches in cross-validation ``fold`` (all of them for ``None``)."""
    if fold is None:
        return list(blocks)
    out = []
    for b in blocks:
        keep = _fold(b.t - state[b.i, 3], s) == fold
        if keep.any():
            out.append(_Block(b.i, b.j, b.rows[keep], b.p[keep], b.t[keep], b.pair))
    return out


def _fold(true_t: np.ndarray, s: WalkSettings) -> np.ndarray:
    """Which of the two cross-validation folds (alternating time blocks) a time is in."""
    return (np.floor(true_t / s.cv_block_s).astype(int) % 2).astype(int)


def _anchor_mean(
    walkers: Sequence[_Walker], current: np.ndarray, solved: np.ndarray
) -> np.ndarray:
    """Move the solved network as one rigid body (and shift its clocks) to keep the walk.

    The rigid motion best maps every walker detection's solved world position onto its
    current one; the clocks move by the mean change of the offsets.
    """
    cur, new = [], []
    for k, w in enumerate(walkers):
        cur.append(w.xy @ _rot(current[k, 2]).T + current[k, :2])
        new.append(w.xy @ _rot(solved[k, 2]).T + solved[k, :2])
    move = _kabsch(np.concatenate(cur), np.concatenate(new))
    out = solved.copy()
    for k in range(len(walkers)):
        pose = move.compose(Pose2D(solved[k, 0], solved[k, 1], math.degrees(solved[k, 2])))
        out[k, :3] = pose.x, pose.y, pose.yaw
    out[:, 3] += float(np.mean(current[:, 3] - solved[:, 3]))
    return out
