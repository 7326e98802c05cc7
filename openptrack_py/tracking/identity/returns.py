r"""How likely a new track is someone from the pool: the prior of re-identification.

A young track is either a stranger or one of the ``N`` pooled identities it could have
walked to. Its appearance evidence against pooled identity ``j`` is a likelihood ratio
``L_j`` ("this pooled person" against "someone else"). Each person who left may come
back, so the chance that a new track is a return grows with the number of people who
could be returning: with the odds ``\rho`` of one given pooled person against a
stranger (a return hazard per absent person over an arrival rate of strangers), the
prior of identity ``j`` is ``\rho / (1 + N \rho)`` and of a stranger ``1 / (1 + N
\rho)``, and Bayes gives

.. math::

    P(j \mid \text{evidence}) = \frac{\rho L_j}{1 + \rho \sum_k L_k} .

So the evidence one link needs grows with the number of look-alike candidates (among
twenty people in dark clothes, one that looks alike is no surprise) and with how rarely
people come back. ``\rho`` is a property of the site, not of the tracker: an
exhibition's visitors rarely return, a classroom's children always do.
:class:`ReturnRate` estimates it online from the young tracks seen so far, as the
proportion of a two-component mixture (stranger, return) whose components' likelihood
ratios are known and whose proportion is not (the same mixture-proportion estimate as
the share of true nulls in the false discovery rate literature, here with a proportion
that depends on each track's candidates). With ``S = \sum_k L_k`` a track's evidence
has likelihood ``(1 + \rho S) / (1 + \rho N)`` up to a factor free of ``\rho``; the
estimate maximises their product times a prior of one return and one stranger among
single candidates (so a handful of tracks cannot drive it to 0 or infinity).

Why odds per pooled person and not one share of returns among new tracks: the first
people of a session all arrive as strangers, while hardly anyone has left yet; a share
learned from them says returns are rare, and a person who comes back once the room
has emptied then needs far more evidence than their look gives. The odds learned from
the same strangers, each met by a pool of one or two, still expect a return when
seven people are out.
"""

from __future__ import annotations

from collections import deque

import numpy as np

MEMORY = 100
"""Young tracks the return odds are estimated from (the most recent)."""
PRIOR_RETURNS = 1.0
"""Pseudo-tracks in the prior: this many returns and as many strangers, one candidate each."""
LOG_ODDS = np.linspace(np.log(1e-4), np.log(1e4), 369)
"""Where the posterior of the odds is evaluated (steps of 0.05 in ``log rho``)."""


class ReturnRate:
    """Online estimate of the odds that a new track is a given pooled person.

    Attributes
    ----------
    odds : float
        ``rho``: the prior odds of one pooled identity against a stranger.

    Parameters
    ----------
    memory : int
        Number of recent young tracks the estimate uses.
    """

    def __init__(self, memory: int = MEMORY) -> None:
        self._tracks: deque[tuple[float, int]] = deque(maxlen=memory)
        self.odds = self._estimate()

    def rate(self, candidates: int) -> float:
        """Prior share of returns among new tracks with ``candidates`` pooled people in reach."""
        return candidates * self.odds / (1.0 + candidates * self.odds)

    def add(self, llrs: np.ndarray) -> None:
        """One young track's settled evidence: mean log-likelihood ratio per candidate.

        A track with no candidate (nobody in the pool could have walked there) tells
        nothing about the odds and is skipped.
        """
        llrs = np.asarray(llrs, dtype=float)
        llrs = llrs[np.isfinite(llrs)]
        if not len(llrs):
            return
        self._tracks.append((float(np.exp(llrs).sum()), len(llrs)))
        self.odds = self._estimate()

    def _estimate(self) -> float:
        """The odds of highest posterior, over :data:`LOG_ODDS` refined by a parabola.

        The log posterior of ``rho`` is ``sum_i [log(1 + rho S_i) - log(1 + rho N_i)]``
        plus the prior's ``log rho - 2 log(1 + rho)``; evaluated on the whole grid at
        once it has no local optimum to stop at.
        """
        total, candidates = np.array(self._tracks, dtype=float).reshape(-1, 2).T
        rho = np.exp(LOG_ODDS)
        post = (
            np.log1p(rho[:, None] * total).sum(axis=1)
            - np.log1p(rho[:, None] * candidates).sum(axis=1)
            + PRIOR_RETURNS * (LOG_ODDS - 2.0 * np.log1p(rho))
        )
        k = int(np.clip(np.argmax(post), 1, len(LOG_ODDS) - 2))
        left, mid, right = post[k - 1 : k + 2]
        bend = left - 2.0 * mid + right
        shift = 0.5 * (left - right) / bend if bend < 0 else 0.0
        step = LOG_ODDS[1] - LOG_ODDS[0]
        return float(np.exp(LOG_ODDS[k] + np.clip(shift, -1.0, 1.0) * step))

    def state(self) -> tuple[str, float, tuple[tuple[float, int], ...]]:
        """For snapshots."""
        return "odds", self.odds, tuple(self._tracks)

    def restore(self, state: tuple) -> None:
        """Return to a :meth:`state`.

        A state saved before the odds were per pooled person holds a share of returns
        and one number per track: the share becomes odds against one candidate and the
        history is dropped.
        """
        self._tracks.clear()
        if state[0] != "odds":
            share = float(state[0])
            self.odds = float(np.clip(share / max(1.0 - share, 1e-9), *np.exp(LOG_ODDS[[0, -1]])))
            return
        self.odds = float(state[1])
        self._tracks.extend(state[2])


def link_posterior(mean_llr: np.ndarray, odds: float) -> np.ndarray:
    """Probability that each candidate track is each pooled identity.

    Parameters
    ----------
    mean_llr : ndarray
        ``(C, P)`` mean log-likelihood ratio of each young track's observations against
        each pooled identity; ``-inf`` where the track could not be that person (out of
        reach, no evidence).
    odds : float
        Prior odds of one pooled identity against a stranger (:class:`ReturnRate`).

    Returns
    -------
    ndarray
        ``(C, P)`` posterior probabilities (0 where out of reach); each row sums to at
        most 1 (the rest is "a stranger").
    """
    lr = np.exp(mean_llr)
    return odds * lr / (1.0 + odds * lr.sum(axis=1, keepdims=True))
