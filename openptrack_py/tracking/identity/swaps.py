"""Identities that two tracks exchanged where their people met, put back by their looks.

Where two people pass close, or one walks behind the other, motion alone cannot tell
which track goes on with whom, and the tracks may come out exchanged: from then on each
publishes the other's identity, for as long as both are tracked. Appearance in
association cannot undo it either, since a track's colour model follows its new person
within seconds. Identity management in multi-target tracking (Shin, Guibas and Zhao,
2003) treats such meetings as the places where identities mix, and local evidence
afterwards as what sorts them out again.

:class:`SwapWatch` keeps, for each pair of tracks that came within a body width of each
other, both identities' looks as they were before they met. Once the two are apart, every
clean observation of either track is compared with both remembered looks. Once each
track has ``min_observations`` and the tracks look, on average, more like each other's
identity than their own by ``margin`` (the sum of the two tracks' mean log-likelihood
ratios, the test that tells two people apart), the identities were exchanged and are
swapped back; once they look more like their own by ``margin``, the pair is settled.
Observations that cannot tell the two apart (two people of one height, seen without
colours) leave it undecided. Where everyone dresses
alike the ratios are near 0 and nothing is ever swapped. Another meeting of the pair
before it is decided starts its evidence again (the looks stay those from before the
first meeting); a pair apart for ``window_s`` without a decision is forgotten.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from openptrack_py.tracking.identity.models import Side

Pair = tuple[int, int]
"""Two track ids, the smaller first."""


@dataclass
class _Watch:
    """One pair's remembered looks (``before[k]`` of ``pair[k]``) and evidence.

    ``evidence[k]``: the sum over track ``pair[k]``'s observations of (log-likelihood
    ratio for the other's identity) - (for its own), and ``count[k]`` their number.
    """

    before: Side
    met: float
    evidence: np.ndarray = field(default_factory=lambda: np.zeros(2))
    count: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def copy(self) -> _Watch:
        return _Watch(self.before, self.met, self.evidence.copy(), self.count.copy())


class SwapWatch:
    """Pairs of tracks that met, watched until their looks say who is who.

    Parameters
    ----------
    margin : float
        Summed mean log-likelihood ratio by which the two tracks must look like each
        other's identity to be swapped.
    window_s : float
        How long after their last meeting a pair is watched.
    min_observations : int
        Clean observations of each track before the pair is decided.
    """

    def __init__(self, margin: float, window_s: float, min_observations: int) -> None:
        self.margin = margin
        self.window_s = window_s
        self.min_observations = min_observations
        self.watches: dict[Pair, _Watch] = {}
        self._pairs_of: dict[int, set[Pair]] = {}
        self._touched: set[Pair] = set()
        self._swept = -np.inf

    def meet(self, pairs: list[Pair], t: float, looks: Callable[[np.ndarray], Side]) -> None:
        """``pairs`` are close at ``t``; ``looks(ids)`` gives tracks' current looks."""
        new = []
        for pair in pairs:
            watch = self.watches.get(pair)
            if watch is None:
                new.append(pair)
            else:  # evidence counts from their last meeting on
                watch.met = t
                watch.evidence[:] = 0.0
                watch.count[:] = 0.0
        if new:
            side = looks(np.array(new, dtype=np.int64).ravel())
            for k, pair in enumerate(new):
                self.watches[pair] = _Watch(side.take(np.array([2 * k, 2 * k + 1])), t)
                for tid in pair:
                    self._pairs_of.setdefault(tid, set()).add(pair)

    def observe(
        self, ids: np.ndarray, seen: Side, t: float, llr: Callable[[Side, Side], np.ndarray]
    ) -> None:
        """Clean observations ``seen`` of tracks ``ids`` (one each); ``llr`` row-wise."""
        if not self.watches or not len(ids):
            return
        index: dict[int, list[int]] = {}
        for k, i in enumerate(ids.tolist()):
            if i in self._pairs_of:
                index.setdefault(i, []).append(k)
        for tid, obs in index.items():
            rows = np.array(obs)
            for pair in self._pairs_of[tid]:
                watch = self.watches[pair]
                if watch.met >= t:
                    continue
                side = pair.index(tid)
                own = np.full(len(rows), side)
                mine = llr(seen.take(rows), watch.before.take(own))
                theirs = llr(seen.take(rows), watch.before.take(1 - own))
                watch.evidence[side] += float((theirs - mine).sum())
                watch.count[side] += len(rows)
                self._touched.add(pair)

    def decide(self, t: float, alive: np.ndarray) -> list[tuple[Pair, Side]]:
        """Pairs whose identities were exchanged, with their looks from before they met.

        Decided pairs are forgotten, and once a second those of which a track is no
        longer among the ``alive`` ids or that are past their window.
        """
        out: list[tuple[Pair, Side]] = []
        for pair in self._touched:
            watch = self.watches.get(pair)
            if watch is None or (watch.count < self.min_observations).any():
                continue
            score = float((watch.evidence / watch.count).sum())
            if abs(score) >= self.margin:
                self._forget(pair)
                if score > 0:
                    out.append((pair, watch.before))
        self._touched = set()
        for (a, b), _ in out:  # what was remembered of them is the other's now
            for pair in list(self._pairs_of.get(a, ())) + list(self._pairs_of.get(b, ())):
                self._forget(pair)
        if t - self._swept >= 1.0:
            self._swept = t
            alive_ids = set(alive.tolist())
            for pair, watch in list(self.watches.items()):
                gone = pair[0] not in alive_ids or pair[1] not in alive_ids
                if gone or t - watch.met > self.window_s:
                    self._forget(pair)
        return out

    def _forget(self, pair: Pair) -> None:
        if self.watches.pop(pair, None) is None:
            return
        for tid in pair:
            pairs = self._pairs_of[tid]
            pairs.discard(pair)
            if not pairs:
                del self._pairs_of[tid]

    def state(self) -> dict[Pair, _Watch]:
        """The watches (independent copies)."""
        return {p: w.copy() for p, w in self.watches.items()}

    def restore(self, state: dict[Pair, _Watch]) -> None:
        """Return to a :meth:`state`."""
        self.watches = {p: w.copy() for p, w in state.items()}
        self._pairs_of = {}
        for pair in self.watches:
            for tid in pair:
                self._pairs_of.setdefault(tid, set()).add(pair)
        self._touched, self._swept = set(), -np.inf
