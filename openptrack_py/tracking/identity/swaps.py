"""Identities that two tracks exchanged where their people met, put back by their looks.

Where two people pass close, or one walks behind the other, motion alone cannot tell
which track goes on with whom, and the tracks may come out exchanged: from then on each
publishes the other's identity, for as long as both are tracked. Appearance in
association cannot undo it either, since a track's colour model follows its new person
within seconds. Identity management in multi-target tracking (Shin, Guibas and Zhao,
2003) treats such meetings as the places where identities mix, and local evidence
afterwards as what sorts them out again.

:class:`SwapWatch` keeps, for each pair of tracks that came within a body width of each
other, both identities' looks as they were before they met. Once the two are apart, each
observation of either track (colours and heights of clean detections, identity
embeddings of any) is compared with both remembered looks. Once each track has
``min_observations`` and the tracks look, on average, more like each other's identity
than their own by ``margin`` (the sum of the two tracks' mean log-likelihood ratios, the
test that tells two people apart), the identities were exchanged and are swapped back;
once they look more like their own by ``margin``, the pair is settled. Observations that
cannot tell the two apart (two people of one height, seen without colours) pull the
means towards 0 and leave the pair undecided; where everyone dresses alike nothing is
ever swapped. Another meeting of the pair before it is decided starts its evidence again
(the looks stay those from before the first meeting); a pair apart for ``window_s``
without a decision is no longer decided, and is forgotten. In one step a track is
swapped at most once, by its most decisive pair (in a group of three that all exchanged
people, one pair is put right at a time).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from openptrack_py.tracking.identity.models import Side

Pair = tuple[int, int]
"""Two track ids, the smaller first."""
SWEEP_S = 1.0
"""How often pairs of ended tracks and past windows are forgotten (seconds)."""


@dataclass(frozen=True)
class _Watch:
    """One pair's remembered looks (``before`` row ``k`` of ``pair[k]``) and evidence.

    ``evidence[k]``: the sum over track ``pair[k]``'s observations of (log-likelihood
    ratio for the other's identity) - (for its own), and ``count[k]`` their number.
    Never changed in place, arrays included (states share it): a change is a new watch.
    """

    before: Side
    met: float
    evidence: np.ndarray = field(default_factory=lambda: np.zeros(2))
    count: np.ndarray = field(default_factory=lambda: np.zeros(2))


class SwapWatch:
    """Pairs of tracks that met, watched until their looks say who is who.

    Parameters
    ----------
    margin : float
        Summed mean log-likelihood ratio by which the two tracks must look like each
        other's identity to be swapped (or like their own to be settled).
    window_s : float
        How long after their last meeting a pair may be decided.
    min_observations : int
        Observations of each track before the pair is decided.
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
                self.watches[pair] = _Watch(watch.before, t)
        if new:
            side = looks(np.array(new, dtype=np.int64).ravel())
            for k, pair in enumerate(new):
                self.watches[pair] = _Watch(side.take(np.array([2 * k, 2 * k + 1])), t)
                for tid in pair:
                    self._pairs_of.setdefault(tid, set()).add(pair)

    def observe(
        self, ids: np.ndarray, seen: Side, t: float, llr: Callable[[Side, Side], np.ndarray]
    ) -> None:
        """Observations ``seen`` of tracks ``ids`` (one each); ``llr`` row-wise.

        Every (observation, watched pair of its track) is compared in one call of
        ``llr`` for the track's own remembered identity and one for the other's.
        """
        if not self.watches or not len(ids):
            return
        obs: list[int] = []
        pairs: list[Pair] = []
        sides: list[int] = []
        for k, i in enumerate(ids.tolist()):
            for pair in self._pairs_of.get(i, ()):
                if self.watches[pair].met < t:
                    obs.append(k)
                    pairs.append(pair)
                    sides.append(0 if pair[0] == i else 1)
        if not obs:
            return
        befores = [self.watches[p].before for p in pairs]
        seen = seen.take(np.array(obs))
        diff = llr(seen, stack_rows(befores, [1 - s for s in sides])) - llr(
            seen, stack_rows(befores, sides)
        )
        for pair, side, d in zip(pairs, sides, diff.tolist(), strict=True):
            watch = self.watches[pair]
            evidence, count = watch.evidence.copy(), watch.count.copy()
            evidence[side] += d
            count[side] += 1.0
            self.watches[pair] = _Watch(watch.before, watch.met, evidence, count)
        self._touched.update(pairs)

    def decide(self, t: float, alive: np.ndarray) -> list[tuple[Pair, Side]]:
        """Pairs whose identities were exchanged, with their looks from before they met.

        Decided pairs are forgotten, and so is every other pair of a swapped track
        (what was remembered of its identity is the other track's now); every
        :data:`SWEEP_S`, so are the pairs of which a track is not among the ``alive``
        ids, and those past their window.
        """
        scored = []
        for pair in self._touched:
            watch = self.watches.get(pair)
            if watch is None or t - watch.met > self.window_s:
                continue
            if (watch.count >= self.min_observations).all():
                score = float((watch.evidence / watch.count).sum())
                if abs(score) >= self.margin:
                    scored.append((score, pair))
        self._touched = set()
        out: list[tuple[Pair, Side]] = []
        swapped: set[int] = set()
        for score, pair in sorted(scored, reverse=True):
            if score > 0 and swapped.isdisjoint(pair):
                out.append((pair, self.watches[pair].before))
                swapped.update(pair)
            self._forget(pair)
        for tid in swapped:
            for pair in list(self._pairs_of.get(tid, ())):
                self._forget(pair)
        if t - self._swept >= SWEEP_S:
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

    def state(self) -> tuple[dict[Pair, _Watch], float]:
        """The watches and the time of the last sweep.

        The watches are shared: they are never changed in place.
        """
        return dict(self.watches), self._swept

    def restore(self, state: tuple[dict[Pair, _Watch], float]) -> None:
        """Return to a :meth:`state`."""
        watches, self._swept = state
        self.watches = dict(watches)
        self._pairs_of = {}
        for pair in self.watches:
            for tid in pair:
                self._pairs_of.setdefault(tid, set()).add(pair)
        self._touched = set()


def stack_rows(befores: list[Side], rows: list[int]) -> Side:
    """Row ``rows[k]`` of ``befores[k]`` for every ``k``, as one :class:`Side`."""
    picks = list(zip(befores, rows, strict=True))

    def col(name: str) -> np.ndarray:
        return np.stack([getattr(b, name)[r] for b, r in picks])

    heights = befores[0].hgt is not None
    return Side(
        col("sig"), col("sig_ok"), col("emb"), col("emb_w"),
        col("hgt") if heights else None, col("hgt_ok") if heights else None,
    )  # fmt: skip
