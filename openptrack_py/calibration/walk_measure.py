"""Disagreement: how far apart the sensors put the walker at the same instant.

Its single role is to measure a calibration by the walk. Over the time-matched
detections the pairwise RANSAC kept (a set that does not depend on the poses being
compared), in the world frame: the median, over sensor pairs and one-second bins of
true time, of the length of the mean difference between one sensor's detections and
the other's linearly interpolated raw detections (time-binned as the refinement of
Munaro et al., OpenPTrack, §4.3, bins its detections; per-frame detector noise averages
out within a bin, what stays is each sensor's persistent error and the calibration's).
The per-frame median and root mean square of those distances are reported too.

For the refinement's cross-validated acceptance, each bin also carries its
cross-validation fold and block, and :func:`_significance` is the one-sided t statistic
of the mean log change of the disagreement over those blocks.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from openptrack_py.calibration.walk_settings import WalkSettings
from openptrack_py.calibration.walk_solve import _Block, _fold, _residuals
from openptrack_py.calibration.walk_tracks import _Walker

__all__ = ["Disagreement"]


@dataclass(frozen=True)
class Disagreement:
    """How far apart the sensors put the walker at the same instant, world frame.

    Parameters
    ----------
    binned_m : float
        Median over sensor pairs and time bins of the length of the mean difference
        between their time-matched detections, metres (the headline figure).
    raw_m : float
        Median distance between time-matched detections, frame by frame, metres.
    rms_m : float
        Root mean square of the per-frame distances, metres.
    pairs : int
        Time-matched pairs of detections measured.
    """

    binned_m: float
    raw_m: float
    rms_m: float
    pairs: int


@dataclass(frozen=True, eq=False)
class _Distances:
    """Time-matched distances: per time bin (fold, pair and block) and per frame (fold)."""

    binned: np.ndarray
    binned_fold: np.ndarray
    binned_block: np.ndarray
    frames: np.ndarray
    frames_fold: np.ndarray

    def summary(self, fold: int | None = None) -> Disagreement:
        binned = self.binned if fold is None else self.binned[self.binned_fold == fold]
        frames = self.frames if fold is None else self.frames[self.frames_fold == fold]
        return _summary(binned, frames)


def _summary(binned: np.ndarray, frames: np.ndarray) -> Disagreement:
    nan = float("nan")
    return Disagreement(
        binned_m=float(np.median(binned)) if len(binned) else nan,
        raw_m=float(np.median(frames)) if len(frames) else nan,
        rms_m=float(np.sqrt(np.mean(frames * frames))) if len(frames) else nan,
        pairs=len(frames),
    )


def _validity(
    walkers: Sequence[_Walker], blocks: Sequence[_Block], states: Sequence[np.ndarray]
) -> list[np.ndarray]:
    """Matches interpolable under every one of ``states`` (a fair common set)."""
    masks = [np.ones(len(b.rows), dtype=bool) for b in blocks]
    for state in states:
        _, valid = _residuals(blocks, walkers, state, raw=True)
        masks = [m & v for m, v in zip(masks, valid, strict=True)]
    return masks


def _distances(
    walkers: Sequence[_Walker],
    blocks: Sequence[_Block],
    state: np.ndarray,
    valid: Sequence[np.ndarray],
    s: WalkSettings,
    clock: np.ndarray | None = None,
) -> _Distances:
    """Raw detection to raw detection distances of ``state`` over the ``valid`` matches.

    Times are binned on the clocks of ``clock`` (``state`` if omitted): with one
    ``clock`` for several states their bins correspond one to one.
    """
    res, _ = _residuals(blocks, walkers, state, raw=True)
    base = state if clock is None else clock
    binned: list[np.ndarray] = []
    binned_fold: list[np.ndarray] = []
    binned_block: list[np.ndarray] = []
    frames: list[np.ndarray] = []
    frames_fold: list[np.ndarray] = []
    by_pair: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
    for b, r, ok in zip(blocks, res, valid, strict=True):
        sign = 1.0 if b.i < b.j else -1.0  # one orientation per pair
        t = b.t[ok] - base[b.i, 3]
        by_pair.setdefault(b.pair, []).append((t, sign * r[ok]))
        frames.append(np.linalg.norm(r[ok], axis=1))
        frames_fold.append(_fold(t, s))
    for pair, chunks in sorted(by_pair.items()):
        t = np.concatenate([c[0] for c in chunks])
        r = np.concatenate([c[1] for c in chunks])
        if not len(t):
            continue
        bins = np.floor(t / s.bin_s).astype(int)
        uniq, inverse, counts = np.unique(bins, return_inverse=True, return_counts=True)
        sums = np.zeros((len(uniq), 2))
        np.add.at(sums, inverse, r)
        full = counts >= 5
        binned.append(np.linalg.norm(sums[full] / counts[full, None], axis=1))
        centre = (uniq[full] + 0.5) * s.bin_s
        binned_fold.append(_fold(centre, s))
        binned_block.append(pair * 1_000_000 + np.floor(centre / s.cv_block_s).astype(int))

    def cat(parts: list[np.ndarray], dtype: type) -> np.ndarray:
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(0, dtype=dtype)

    return _Distances(
        cat(binned, float),
        cat(binned_fold, int),
        cat(binned_block, int),
        cat(frames, float),
        cat(frames_fold, int),
    )


def _significance(log_ratio: np.ndarray, block: np.ndarray) -> float:
    """One-sided t statistic of the mean log change of the disagreement over blocks.

    Bins of one pair and one cross-validation block are averaged first (their errors
    are correlated in time); the blocks are then taken as independent. Negative: the
    disagreement falls. ``nan`` with fewer than three blocks.
    """
    if not len(log_ratio):
        return math.nan
    keys, inverse = np.unique(block, return_inverse=True)
    if len(keys) < 3:
        return math.nan
    sums = np.bincount(inverse, weights=log_ratio)
    means = sums / np.bincount(inverse)
    spread = float(np.std(means, ddof=1))
    if spread == 0.0:
        return -math.inf if means.mean() < 0 else math.inf
    return float(means.mean() / (spread / math.sqrt(len(means))))
