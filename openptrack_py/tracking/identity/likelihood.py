"""How much a distance between two looks says about "same person", learned online.

A fixed similarity threshold is right for one camera, one lighting and one crowd: it
makes identity help where people dress differently and hurt where they dress alike. The
tracker instead learns, from its own associations that motion alone made certain, two
distributions of the distance between a detection's look and a track's model:

* *same*: the detection was the only one in the track's gate and the track the only
  one in the detection's gate;
* *different*: the same detection against the models of other confirmed tracks more
  than a body width away (certainly someone else).

A distance ``d`` then weighs ``ln p_same(d) / p_diff(d)``, the log-likelihood ratio,
in the association cost and the re-identification evidence, as the Bayes recogniser of
OpenPTrack v2's face recognition weighs face distances with a same-person and a
different-person density (there fixed skew-normal fits; here histograms that keep
learning). Both start from the same prior, so the ratio is 0 (no opinion) until
evidence comes in; where everyone looks alike the two stay alike and the ratio near 0,
so identity cannot make tracking worse. Old samples fade (``half_life`` samples), so the
model follows lighting that changes over a day.

The ratio is fitted non-increasing in the distance (weighted isotonic regression): a
look farther from a model is never more likely to be that person. Without it the sparse
far bins, where the prior pseudo-counts weigh most, favour whichever kind has fewer
samples there; a very different face could count *for* a person.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import isotonic_regression

from openptrack_py.tracking.neighbours import far_pairs

BINS = 32
"""Histogram bins over distances in [0, 1]."""
PRIOR = 2.0
"""Pseudo-count per bin of both histograms (equal: the ratio starts at 0)."""
MIN_SAMPLES = 50.0
"""Samples each histogram needs before the ratio is used at all."""
MAX_DIFFERENT_SAMPLES = 64
"""Different-person distances learned per step at most."""
HEIGHT_RANGE_M = 0.5
"""Height differences from 0 to this map to distances 0 to 1 (larger ones to 1): bins of
1.6 cm, finer than a depth sensor measures a height."""
ISOLATION_M = 1.5
"""A detection is certainly not the person of a track farther than this (a "different"
sample)."""


class DistanceLikelihood:
    """Online log-likelihood ratio of "same person" for distances in [0, 1].

    Parameters
    ----------
    max_llr : float
        Largest absolute ratio returned.
    half_life : float
        Samples after which an old sample weighs half.
    """

    def __init__(self, max_llr: float = 3.0, half_life: float = 5000.0) -> None:
        self.max_llr = max_llr
        self.decay = 0.5 ** (1.0 / half_life)
        self.counts = np.zeros((2, BINS))
        self.table = np.zeros(BINS)

    def learn(self, same: np.ndarray, different: np.ndarray) -> None:
        """Add distances of pairs known to be one person (``same``) and two people."""
        for k, d in enumerate((same, different)):
            if len(d):
                self.counts[k] *= self.decay ** len(d)
                self.counts[k] += np.bincount(_bins(d), minlength=BINS)
        self._refresh()

    def _refresh(self) -> None:
        n = self.counts.sum(axis=1)
        if (n < MIN_SAMPLES).any():
            self.table = np.zeros(BINS)
            return
        # a little smoothing across neighbouring bins, so empty bins do not spike
        smooth = self.counts + PRIOR
        smooth = (np.roll(smooth, 1, axis=1) + 2 * smooth + np.roll(smooth, -1, axis=1)) / 4
        p = smooth / smooth.sum(axis=1, keepdims=True)
        # non-increasing in the distance, each bin weighing by the samples it holds
        ratio = np.log(p[0] / p[1])
        fit = isotonic_regression(ratio, weights=smooth.sum(axis=0), increasing=False)
        self.table = np.clip(fit.x, -self.max_llr, self.max_llr)

    @property
    def ready(self) -> bool:
        """Whether enough of both kinds were seen for the ratio to mean something."""
        return bool((self.counts.sum(axis=1) >= MIN_SAMPLES).all())

    def llr(self, distance: np.ndarray) -> np.ndarray:
        """Log-likelihood ratio of "same person" for each distance (0 until ready)."""
        return self.table[_bins(distance)]

    def separation(self) -> float:
        """How well the distance tells people apart: the ratio's mean over same pairs.

        The Kullback-Leibler divergence of *same* from *different*; 0 when they look
        alike, a few nats when appearance is telling.
        """
        if not self.ready:
            return 0.0
        p = self.counts[0] + PRIOR
        return float((p / p.sum() * self.table).sum())

    def state(self) -> np.ndarray:
        """The counts (a copy): everything needed to restore the model."""
        return self.counts.copy()

    def restore(self, counts: np.ndarray) -> None:
        """Return to counts taken by :meth:`state`."""
        self.counts = counts.copy()
        self._refresh()


def _bins(distance: np.ndarray) -> np.ndarray:
    return np.clip((np.asarray(distance) * BINS).astype(np.int64), 0, BINS - 1)


def hellinger(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hellinger distances ``(n, m)`` between rows of two sets of histograms summing to 1.

    ``sqrt(1 - BC)`` with BC the Bhattacharyya coefficient: 0 for equal histograms, 1
    for histograms with no bin in common.
    """
    bc = np.sqrt(np.maximum(a, 0.0)) @ np.sqrt(np.maximum(b, 0.0)).T
    return np.sqrt(np.clip(1.0 - bc, 0.0, 1.0))


def cosine_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances ``(n, m)`` in [0, 1] between rows of unit vectors: ``(1 - cos) / 2``."""
    return np.clip((1.0 - a @ b.T) / 2.0, 0.0, 1.0)


def height_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances ``(n, m)`` in [0, 1] between heights ``(n, 1)`` and ``(m, 1)``, metres."""
    return np.minimum(np.abs(a - b.T) / HEIGHT_RANGE_M, 1.0)


PAIRWISE = {"hellinger": hellinger, "cosine": cosine_distance, "height": height_distance}
"""Each distance between every row of one set and every row of another, by kind."""


def rowwise_distance(kind: str, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances between rows ``a[k]`` and ``b[k]`` ("hellinger", "cosine" or "height")."""
    if kind == "height":
        return np.minimum(np.abs(a - b).sum(axis=1) / HEIGHT_RANGE_M, 1.0)
    if kind == "hellinger":
        bc = (np.sqrt(np.maximum(a, 0.0)) * np.sqrt(np.maximum(b, 0.0))).sum(axis=1)
        return np.sqrt(np.clip(1.0 - bc, 0.0, 1.0))
    return np.clip((1.0 - (a * b).sum(axis=1)) / 2.0, 0.0, 1.0)


def distance_samples(
    refs: np.ndarray,
    ready: np.ndarray,
    mrows: np.ndarray,
    looks: np.ndarray,
    same_ok: np.ndarray,
    use: np.ndarray,
    where: tuple[np.ndarray, np.ndarray],
    others: np.ndarray,
    confirmed: np.ndarray,
    kind: str,
) -> tuple[np.ndarray, np.ndarray]:
    """Same-person and different-person distances from one step's updates.

    ``refs`` are the tracks' models (``ready`` where settled), ``mrows`` each update's
    model row and ``looks`` its detection's look. *Same*: the updates ``same_ok`` (motion
    alone made them certain) against their own track's model. *Different*: the updates
    ``use`` against the models of the confirmed tracks more than :data:`ISOLATION_M`
    from them, the first :data:`MAX_DIFFERENT_SAMPLES` such pairs in update order.
    ``where``: the updates' detection positions and every table track's position;
    ``others``: the model row of every track of the table, ``-1`` for none.
    """
    same_sel = same_ok & ready[mrows]
    same = rowwise_distance(kind, refs[mrows[same_sel]], looks[same_sel])
    valid = (others >= 0) & confirmed
    valid[valid] &= ready[others[valid]]
    different = np.zeros(0)
    sel = np.flatnonzero(use)
    if len(sel) and valid.any():
        cand = np.flatnonzero(valid)
        det_xy, track_xy = where
        i, j = far_pairs(det_xy[sel], track_xy[cand], ISOLATION_M, MAX_DIFFERENT_SAMPLES)
        different = rowwise_distance(kind, looks[sel[i]], refs[others[cand[j]]])
    return same, different
