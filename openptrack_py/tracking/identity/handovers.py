"""Tracks that came back from a gap following someone else: split off by their looks.

Where a visitor walks out through a door and another comes in through it a moment
later, the leaver's track, coasting where it lost its person, takes the newcomer's
detections: nothing in the assignment offers the newcomer a track of their own, and the
appearance term only ranks the pairs the gate admits. From then on the newcomer
publishes the leaver's identity. Motion cannot tell the two apart; looks can.

:class:`GapWatch` remembers a track's looks when it is observed again after
``gap_s`` without an observation, and compares each later observation that has a cue
(a clean colour, a height, an identity embedding) with them. Once it has
``min_observations`` and their mean log-likelihood ratio of "the same person" is below
``-margin``, the track follows someone else since the gap, and the tracker splits it
(the newcomer gets a new track and identity, the old identity goes to the pool, where
the leaver, coming back, can take it). A mean above ``margin`` settles the watch; one
undecided after ``window_s`` is dropped. Where everyone looks alike the means stay near
0 and nothing is split. The same test as :mod:`.swaps`, for one track and its past.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from openptrack_py.tracking.identity.models import Side
from openptrack_py.tracking.identity.swaps import stack_rows

GAP_S = 0.5
"""Time without an observation after which a track's next person is put to the test:
twice the tracker's visibility timeout, a person walks about 0.6 m in it."""


@dataclass(frozen=True)
class _Gap:
    """A track's looks from before its gap, and the evidence since.

    Never changed in place (states share it). ``lost_at`` and ``since``: when it was
    last observed before the gap, and first after.
    """

    before: Side
    lost_at: float
    since: float
    evidence: float = 0.0
    count: int = 0


class GapWatch:
    """Tracks observed again after a gap, watched until their looks say who they follow.

    Parameters
    ----------
    margin : float
        Mean log-likelihood ratio below ``-margin`` splits the track, above settles it.
    window_s : float
        How long after the gap the track may be split.
    min_observations : int
        Observations with a cue before the watch decides.
    gap_s : float
        Time without an observation that starts a watch.
    """

    def __init__(
        self, margin: float, window_s: float, min_observations: int, gap_s: float = GAP_S
    ) -> None:
        self.margin = margin
        self.window_s = window_s
        self.min_observations = min_observations
        self.gap_s = gap_s
        self.watches: dict[int, _Gap] = {}
        self.last: dict[int, float] = {}

    def seen(
        self, ids: np.ndarray, ready: np.ndarray, t: float, looks: Callable[[np.ndarray], Side]
    ) -> None:
        """Tracks ``ids`` are observed at ``t``, before anything is learned from it.

        ``ready``: the tracks whose looks are known well enough to be compared;
        ``looks(ids)`` gives tracks' current looks.
        """
        start = [
            i
            for i, ok in zip(ids.tolist(), ready.tolist(), strict=True)
            if ok and i not in self.watches and t - self.last.get(i, t) > self.gap_s
        ]
        if start:
            side = looks(np.array(start, dtype=np.int64))
            for k, tid in enumerate(start):
                self.watches[tid] = _Gap(side.take(np.array([k])), self.last[tid], t)
        self.last.update(dict.fromkeys(ids.tolist(), t))

    def observe(
        self, ids: np.ndarray, seen: Side, llr: Callable[[Side, Side], np.ndarray]
    ) -> None:
        """Observations ``seen`` of tracks ``ids`` (one each, with a cue); ``llr`` row-wise."""
        obs = [k for k, i in enumerate(ids.tolist()) if i in self.watches]
        if not obs:
            return
        tids = [int(ids[k]) for k in obs]
        watched = [self.watches[tid] for tid in tids]
        befores = stack_rows([w.before for w in watched], [0] * len(watched))
        values = llr(seen.take(np.array(obs)), befores).tolist()
        for tid, w, v in zip(tids, watched, values, strict=True):
            self.watches[tid] = _Gap(w.before, w.lost_at, w.since, w.evidence + v, w.count + 1)

    def decide(self, t: float, alive: np.ndarray) -> dict[int, float]:
        """Track ids found to follow someone else since their gap, with their ``lost_at``.

        Decided and expired watches, and those of tracks no longer ``alive``, are forgotten.
        """
        if len(self.last) > 2 * len(alive):  # ended tracks' ids never come back
            kept = set(alive.tolist())
            self.last = {i: s for i, s in self.last.items() if i in kept}
        out: dict[int, float] = {}
        if not self.watches:
            return out
        live = set(alive.tolist())
        for tid, w in list(self.watches.items()):
            mean = w.evidence / w.count if w.count >= self.min_observations else 0.0
            if mean < -self.margin and tid in live:
                out[tid] = w.lost_at
            decided = abs(mean) > self.margin
            if decided or tid not in live or t - w.since > self.window_s:
                del self.watches[tid]
        return out

    def state(self) -> tuple[dict[int, _Gap], dict[int, float]]:
        """The watches (shared: never changed in place) and the last observations."""
        return dict(self.watches), dict(self.last)

    def restore(self, state: tuple[dict[int, _Gap], dict[int, float]]) -> None:
        """Return to a :meth:`state`."""
        watches, last = state
        self.watches = dict(watches)
        self.last = dict(last)
