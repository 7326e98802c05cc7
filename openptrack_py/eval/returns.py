"""Returns: a person who left the sensors' view for a while and came back.

A re-identifying tracker should give a returning person the identity they had before.
:class:`ReturnLog` watches every ground-truth person's CLEAR MOT match frame by frame;
a *return* is a reappearance after at least :data:`MIN_ABSENCE_S` out of view (absent
from the scored frames). The return *kept its identity* when the hypothesis the person
was matched to most in the :data:`BEFORE_S` before leaving is the one they are matched
to most from :data:`SETTLE_S` to :data:`SETTLE_S` + :data:`JUDGE_S` after coming back
(a re-identifier needs a moment of evidence). A return without matches on either side is
not judged (nothing was there to keep).
"""

from __future__ import annotations

from collections import Counter, defaultdict

import numpy as np
from numpy.typing import NDArray

MIN_ABSENCE_S = 5.0
"""Out of view at least this long (seconds) for a reappearance to be a return."""
BEFORE_S = 3.0
"""The identity before leaving: the most matched hypothesis in this window, seconds."""
SETTLE_S = 2.0
"""Time after coming back before the identity is judged, seconds."""
JUDGE_S = 5.0
"""Length of the window the identity after coming back is judged in, seconds."""


class ReturnLog:
    """Every person's matches over time, to judge their returns."""

    def __init__(self) -> None:
        self._seen: dict[int, list[tuple[float, int]]] = defaultdict(list)

    def add_frame(self, t: float, gt: NDArray[np.int64], matched_hyp: NDArray[np.int64]) -> None:
        """One scored frame: each present person and its matched hypothesis (-1: none)."""
        for o, h in zip(gt.tolist(), matched_hyp.tolist(), strict=True):
            self._seen[o].append((t, h))

    def returns(self) -> tuple[int, int]:
        """``(judged returns, returns that kept their identity)``."""
        judged = kept = 0
        for frames in self._seen.values():
            times = np.array([f[0] for f in frames])
            hyps = np.array([f[1] for f in frames])
            for k in np.flatnonzero(np.diff(times) >= MIN_ABSENCE_S):
                left, back = times[k], times[k + 1]
                before = hyps[(times > left - BEFORE_S) & (times <= left) & (hyps >= 0)]
                window = (times >= back + SETTLE_S) & (times < back + SETTLE_S + JUDGE_S)
                after = hyps[window & (hyps >= 0)]
                if not len(before) or not len(after):
                    continue
                judged += 1
                old = Counter(before.tolist()).most_common(1)[0][0]
                new = Counter(after.tolist()).most_common(1)[0][0]
                kept += old == new
        return judged, kept
