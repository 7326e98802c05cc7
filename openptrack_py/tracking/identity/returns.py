r"""How likely a new track is someone from the pool: the prior of re-identification.

A young track is either a stranger or one of the pooled identities it could have
walked to. Its appearance evidence against pooled identity ``j`` is a likelihood ratio
``L_j`` ("this pooled person" against "someone else"). With a share ``r`` of new tracks
being returns, spread evenly over the ``N`` reachable pooled identities, Bayes gives

.. math::

    P(j \mid \text{evidence}) = \frac{r L_j / N}{(1 - r) + r \bar L},
    \qquad \bar L = \frac{1}{N} \sum_k L_k .

So the evidence one link needs grows with the number of candidates (among twenty people
in dark clothes, one that looks alike is no surprise) and with how rarely people come
back. ``r`` is a property of the site, not of the tracker: an exhibition's visitors
rarely return, a classroom's children always do. :class:`ReturnRate` estimates it
online from the young tracks seen so far by expectation-maximisation over the
two-component mixture (stranger, return) whose components' likelihood ratios are known
and whose proportion is not: each track's ``\bar L`` gives its responsibility
``r \bar L / ((1 - r) + r \bar L)``, and ``r`` is their mean, with a Beta(2, 2) prior so
a handful of tracks cannot drive it to 0 or 1. The same mixture-proportion estimate
appears in the false discovery rate literature (the share of true nulls).
"""

from __future__ import annotations

from collections import deque

import numpy as np

MEMORY = 100
"""Young tracks the return rate is estimated from (the most recent)."""
PRIOR = (2.0, 2.0)
"""Beta prior on the return rate: one return and one stranger seen before any track."""
EM_STEPS = 25


class ReturnRate:
    """Online estimate of the share of new tracks that are returning people.

    Parameters
    ----------
    memory : int
        Number of recent young tracks the estimate uses.
    """

    def __init__(self, memory: int = MEMORY) -> None:
        self._mean_lr: deque[float] = deque(maxlen=memory)
        self.rate = self._estimate(0.5)

    def add(self, llrs: np.ndarray) -> None:
        """One young track's settled evidence: mean log-likelihood ratio per candidate.

        A track with no candidate (nobody in the pool could have walked there) tells
        nothing about the rate and is skipped.
        """
        llrs = np.asarray(llrs, dtype=float)
        llrs = llrs[np.isfinite(llrs)]
        if not len(llrs):
            return
        self._mean_lr.append(float(np.exp(llrs).mean()))
        self.rate = self._estimate(self.rate)

    def _estimate(self, start: float) -> float:
        a, b = PRIOR
        m = np.array(self._mean_lr)
        r = start
        for _ in range(EM_STEPS):
            resp = r * m / ((1.0 - r) + r * m)
            r = (resp.sum() + a - 1.0) / (len(m) + a + b - 2.0)
        return float(r)

    def state(self) -> tuple[float, tuple[float, ...]]:
        """For snapshots."""
        return self.rate, tuple(self._mean_lr)

    def restore(self, state: tuple[float, tuple[float, ...]]) -> None:
        """Return to a :meth:`state`."""
        self.rate = state[0]
        self._mean_lr.clear()
        self._mean_lr.extend(state[1])


def link_posterior(mean_llr: np.ndarray, rate: float) -> np.ndarray:
    """Probability that each candidate track is each pooled identity.

    Parameters
    ----------
    mean_llr : ndarray
        ``(C, P)`` mean log-likelihood ratio of each young track's observations against
        each pooled identity; ``-inf`` where the track could not be that person (out of
        reach, no evidence).
    rate : float
        Prior share of new tracks that are returns (:class:`ReturnRate`).

    Returns
    -------
    ndarray
        ``(C, P)`` posterior probabilities (0 where out of reach); each row sums to at
        most 1 (the rest is "a stranger").
    """
    lr = np.exp(mean_llr)
    reachable = np.isfinite(mean_llr).sum(axis=1, keepdims=True)
    n = np.maximum(reachable, 1)
    mean = lr.sum(axis=1, keepdims=True) / n
    return rate * lr / n / ((1.0 - rate) + rate * mean)
