"""Duplicate tracks: a second hypothesis following a person who already has one.

In one frame, after the CLEAR MOT matching, an unmatched hypothesis *duplicates* a matched
object when it is within the match threshold of it and nearer to it than to any unmatched
object (two people walking side by side, each with their own track, are therefore not
duplicates). Duplicates are grouped into episodes: a maximal run of frames in which the
same hypothesis duplicates the same object, a gap of up to :data:`DUPLICATE_GAP_S`
between two of its frames not ending it. An episode lasts from its first frame to its
last and counts when it lasts more than :data:`DUPLICATE_MIN_S`: a tracker that holds two
tracks on one person for a moment while it decides is not punished, one that keeps
following a person twice is.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

DUPLICATE_MIN_S = 1.0
"""A duplicate episode counts when it lasts longer than this, seconds."""
DUPLICATE_GAP_S = 0.2
"""A duplicate episode survives gaps up to this long between two of its frames, seconds."""


def check_seconds(name: str, value: float) -> float:
    """Validate a duration: a finite number >= 0, returned as a float.

    Raises
    ------
    ValueError
        Naming ``name``, if ``value`` is negative or not finite.
    """
    if not (math.isfinite(value) and value >= 0.0):
        raise ValueError(f"{name} must be a finite number >= 0 (seconds); got {value!r}")
    return float(value)


class DuplicateLog:
    """The duplicates of every frame, and the episodes they make.

    Parameters
    ----------
    min_s : float
        An episode counts when it lasts longer than this, seconds.
    gap_s : float
        Longest gap between two frames of one episode, seconds.

    Raises
    ------
    ValueError
        If a duration is negative or not finite.
    """

    def __init__(self, min_s: float = DUPLICATE_MIN_S, gap_s: float = DUPLICATE_GAP_S) -> None:
        self.min_s = check_seconds("duplicate_min_s", min_s)
        self.gap_s = check_seconds("duplicate_gap_s", gap_s)
        # one entry per (frame, duplicating hypothesis): frame time, hypothesis, object
        self._time: list[float] = []
        self._hyp: list[int] = []
        self._gt: list[int] = []

    def add_frame(
        self,
        time_s: float,
        gt: NDArray[np.int64],
        hyp: NDArray[np.int64],
        dist: NDArray[np.float64],
        gt_matched: NDArray[np.bool_],
        hyp_taken: NDArray[np.bool_],
    ) -> None:
        """Record the unmatched hypotheses of one frame that follow a matched object.

        Parameters
        ----------
        time_s : float
            Time of the frame, seconds.
        gt, hyp : numpy.ndarray of int64
            The frame's object and hypothesis ids.
        dist : numpy.ndarray, shape (len(gt), len(hyp))
            Distances, ``inf`` beyond the match threshold.
        gt_matched, hyp_taken : numpy.ndarray of bool
            Which objects and hypotheses the matching paired.
        """
        for j in np.flatnonzero(~hyp_taken).tolist():
            to_matched = np.where(gt_matched, dist[:, j], np.inf)
            i = int(np.argmin(to_matched))
            nearest = to_matched[i]
            if not np.isfinite(nearest):
                continue
            to_free = dist[~gt_matched, j]
            if to_free.size and not nearest < to_free.min():
                continue
            self._time.append(time_s)
            self._hyp.append(int(hyp[j]))
            self._gt.append(int(gt[i]))

    def episodes(self) -> tuple[int, float]:
        """The number of episodes longer than ``min_s`` and their total duration, seconds."""
        if not self._time:
            return 0, 0.0
        time_s = np.asarray(self._time, dtype=np.float64)
        hyp = np.asarray(self._hyp, dtype=np.int64)
        gt = np.asarray(self._gt, dtype=np.int64)
        order = np.lexsort((time_s, hyp, gt))
        t, h, g = time_s[order], hyp[order], gt[order]
        new = np.r_[True, (g[1:] != g[:-1]) | (h[1:] != h[:-1]) | (np.diff(t) > self.gap_s)]
        starts = np.flatnonzero(new)
        ends = np.r_[starts[1:], t.size] - 1
        lasted = t[ends] - t[starts]
        counted = lasted[lasted > self.min_s]
        return int(counted.size), float(counted.sum())
