"""CLEAR MOT and identity (IDF1) metrics for people tracked on the ground plane.

Ground truth and tracker output are compared frame by frame with Euclidean distances in
metres; a ground-truth object and a hypothesis can only correspond when they are at most
``max_distance_m`` apart.

The per-frame correspondence follows the CLEAR MOT procedure [1]_ as implemented by
py-motmetrics 1.4 [3]_:

1. Every ground-truth object keeps the hypothesis it was last matched to (in any earlier
   frame) if that hypothesis is present, not yet taken in this frame and within the
   threshold. Objects are visited in the order their ids were given.
2. The remaining objects and hypotheses are paired by a linear assignment restricted to
   pairs within the threshold: the largest possible number of pairs, and among those the
   smallest total distance.
3. Unpaired objects are misses (FN), unpaired hypotheses are false positives (FP).

A pair made in step 2 is an identity switch when the object had already been matched
before, in any earlier frame, and its most recent hypothesis differs. A hypothesis that
moves from one object to another (a "transfer" in py-motmetrics) is not a switch.

A *duplicate* is a second track following an object that is already matched; episodes
of one longer than a second are counted (:mod:`~openptrack_py.eval.duplicates`).

The identity measures IDF1, IDP and IDR [2]_ come from a global one-to-one assignment of
ground-truth trajectories to hypothesis trajectories that maximises the number of frames
in which an assigned pair is within the threshold (the identity true positives, IDTP).

This module keeps the history (the accumulator) and the result type; the validation of
each frame's input, the gating and the step-2 assignment are in
:mod:`~openptrack_py.eval.matching`, the identity assignment in
:mod:`~openptrack_py.eval.identity`, the duplicates in
:mod:`~openptrack_py.eval.duplicates`.

References
----------
.. [1] K. Bernardin and R. Stiefelhagen, "Evaluating multiple object tracking
   performance: the CLEAR MOT metrics", EURASIP Journal on Image and Video Processing,
   2008.
.. [2] E. Ristani, F. Solera, R. Zou, R. Cucchiara and C. Tomasi, "Performance measures
   and a data set for multi-target, multi-camera tracking", ECCV Workshops, 2016.
.. [3] C. Heindl et al., py-motmetrics, https://github.com/cheind/py-motmetrics

Examples
--------
>>> acc = MotAccumulator(max_distance_m=0.5)
>>> acc.update([1, 2], [[0.0, 0.0], [2.0, 0.0]], [7, 8], [[0.1, 0.0], [2.0, 0.2]])
>>> acc.update_missing_frame([1, 2], [[0.0, 0.1], [2.0, 0.1]])
>>> m = acc.compute()
>>> m.fn, m.matches, round(m.mota, 3), round(m.motp, 3)
(2, 2, 0.5, 0.15)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from openptrack_py.eval.duplicates import DUPLICATE_GAP_S, DUPLICATE_MIN_S, DuplicateLog
from openptrack_py.eval.identity import identity_true_positives
from openptrack_py.eval.matching import (
    EMPTY_IDS,
    as_ids,
    as_points,
    check_max_distance,
    distance_matrix,
    max_matching_min_cost,
    pairwise_distances,
)
from openptrack_py.eval.returns import ReturnLog

__all__ = ["DUPLICATE_GAP_S", "DUPLICATE_MIN_S", "MotAccumulator", "MotMetrics", "distance_matrix"]

# A ground-truth track matched in at least this fraction of its frames is mostly tracked.
_MOSTLY_TRACKED_RATIO = 0.8
# A ground-truth track matched in less than this fraction of its frames is mostly lost.
_MOSTLY_LOST_RATIO = 0.2


@dataclass(frozen=True)
class MotMetrics:
    """Summary of a tracking run scored against ground truth.

    Parameters
    ----------
    mota : float
        Multiple object tracking accuracy, ``1 - (fn + fp + id_switches) / gt_objects``;
        NaN when there are no ground-truth objects.
    motp : float
        Mean Euclidean distance in metres over all matched pairs; NaN without matches.
    idf1 : float
        Identity F1 score, ``2 IDTP / (gt_objects + hyp_objects)``; NaN if both are 0.
    idp : float
        Identity precision, ``IDTP / hyp_objects``; NaN without hypotheses.
    idr : float
        Identity recall, ``IDTP / gt_objects``; NaN without ground-truth objects.
    precision : float
        ``matches / hyp_objects``; NaN without hypotheses.
    recall : float
        ``matches / gt_objects``; NaN without ground-truth objects.
    fp : int
        Hypotheses not matched to any ground-truth object (false positives).
    fn : int
        Ground-truth objects not matched to any hypothesis (misses).
    id_switches : int
        Matches whose hypothesis differs from the object's previous match.
    fragmentations : int
        Times a ground-truth track goes from matched to missed and is matched again later.
    matches : int
        Matched (object, hypothesis) pairs summed over frames, switches included (this is
        ``num_detections`` in py-motmetrics, whose ``num_matches`` excludes switches).
    frames : int
        Number of frames scored.
    gt_objects : int
        Ground-truth objects present, summed over frames.
    hyp_objects : int
        Hypotheses present, summed over frames.
    gt_tracks : int
        Distinct ground-truth ids.
    hyp_tracks : int
        Distinct hypothesis ids.
    mostly_tracked : int
        Ground-truth ids matched in at least 80 % of the frames they are present in.
    partially_tracked : int
        Ground-truth ids matched in at least 20 % and less than 80 % of their frames.
    mostly_lost : int
        Ground-truth ids matched in less than 20 % of their frames.
    duplicates : int
        Duplicate episodes (a second hypothesis following an object that is already
        matched) that last longer than ``duplicate_min_s``.
    duplicate_s : float
        Total duration of those episodes, seconds.
    returns : int
        People who came back after :data:`~openptrack_py.eval.returns.MIN_ABSENCE_S`
        out of view, matched before leaving and after coming back.
    returns_kept : int
        Those matched to the same hypothesis id before and after (their identity was
        recognised; see :mod:`openptrack_py.eval.returns`).
    """

    mota: float
    motp: float
    idf1: float
    idp: float
    idr: float
    precision: float
    recall: float
    fp: int
    fn: int
    id_switches: int
    fragmentations: int
    matches: int
    frames: int
    gt_objects: int
    hyp_objects: int
    gt_tracks: int
    hyp_tracks: int
    mostly_tracked: int
    partially_tracked: int
    mostly_lost: int
    duplicates: int
    duplicate_s: float
    returns: int = 0
    returns_kept: int = 0

    def to_dict(self) -> dict[str, float | int | None]:
        """Return the metrics as a JSON-friendly dictionary.

        Returns
        -------
        dict of str to float, int or None
            One entry per field, in declaration order. Non-finite floats (NaN) become
            ``None`` so the result can be written with any JSON encoder.
        """
        out: dict[str, float | int | None] = {}
        for field in fields(self):
            value = getattr(self, field.name)
            if isinstance(value, float) and not math.isfinite(value):
                out[field.name] = None
            else:
                out[field.name] = value
        return out


class MotAccumulator:
    """Accumulate per-frame correspondences and compute CLEAR MOT and IDF1 metrics.

    Parameters
    ----------
    max_distance_m : float, optional
        Largest Euclidean distance in metres at which a ground-truth object and a
        hypothesis may correspond. Must be finite and > 0. Default 0.5.
    duplicate_min_s : float, optional
        A duplicate episode counts when it lasts longer than this, seconds. Default 1.0.
    duplicate_gap_s : float, optional
        Longest gap between two frames of one duplicate episode, seconds. Default 0.2.
    frame_rate_hz : float, optional
        Frames added without a ``time_s`` are taken to follow each other at this rate
        (only duplicate episodes use time). Default 30.

    Raises
    ------
    ValueError
        If ``max_distance_m`` is not a finite number > 0, or a duration or the rate is
        negative or not finite.

    Notes
    -----
    Matching, misses, false positives and switches are decided in :meth:`update` (they
    depend on the history); per-frame ids and gated pairs are stored as small arrays and
    the track-level measures (fragmentations, mostly tracked/lost, IDF1) are computed with
    numpy in :meth:`compute`. The accumulator can be computed again after more updates.

    Examples
    --------
    >>> acc = MotAccumulator(max_distance_m=0.5)
    >>> acc.update([1], [[0.0, 0.0]], [7], [[0.2, 0.0]])
    >>> acc.compute().mota
    1.0
    """

    def __init__(
        self,
        max_distance_m: float = 0.5,
        *,
        duplicate_min_s: float = DUPLICATE_MIN_S,
        duplicate_gap_s: float = DUPLICATE_GAP_S,
        frame_rate_hz: float = 30.0,
    ) -> None:
        self._max_distance_m = check_max_distance(max_distance_m)
        self._duplicates = DuplicateLog(duplicate_min_s, duplicate_gap_s)
        self._returns = ReturnLog()
        if not (math.isfinite(frame_rate_hz) and frame_rate_hz > 0.0):
            raise ValueError(f"frame_rate_hz must be a finite number > 0; got {frame_rate_hz!r}")
        self._frame_period_s = 1.0 / frame_rate_hz
        # ground-truth id -> hypothesis id of its most recent match (any earlier frame)
        self._last_hyp: dict[int, int] = {}
        self._frames = 0
        self._fp = 0
        self._fn = 0
        self._switches = 0
        self._matches = 0
        self._distance_sum = 0.0
        self._gt_ids: list[NDArray[np.int64]] = []
        self._gt_matched: list[NDArray[np.bool_]] = []
        self._hyp_ids: list[NDArray[np.int64]] = []
        self._pair_gt: list[NDArray[np.int64]] = []
        self._pair_hyp: list[NDArray[np.int64]] = []

    @property
    def frames(self) -> int:
        """Number of frames added so far, missing frames included."""
        return self._frames

    def update(
        self,
        gt_ids: ArrayLike,
        gt_xy: ArrayLike,
        hyp_ids: ArrayLike,
        hyp_xy: ArrayLike,
        time_s: float | None = None,
    ) -> None:
        """Add one frame of ground truth and tracker output.

        Parameters
        ----------
        gt_ids : sequence of int, length n
            Ground-truth ids present in the frame, unique within the frame.
        gt_xy : array_like, shape (n, 2) or (n, 3)
            Ground-truth positions in metres.
        hyp_ids : sequence of int, length m
            Hypothesis (track) ids output by the tracker, unique within the frame.
        hyp_xy : array_like, shape (m, 2) or (m, 3)
            Hypothesis positions in metres; same number of coordinates as ``gt_xy`` when
            both are non-empty.
        time_s : float, optional
            Time of the frame, seconds (any origin, increasing). Without it the frame
            comes one period of ``frame_rate_hz`` after the previous one. Give it for
            every frame or for none.

        Raises
        ------
        ValueError
            If ids are not 1-D integers, repeat within the frame, or do not match the
            number of positions; if positions have the wrong shape or are not finite.
        """
        gt = as_ids(gt_ids, "gt_ids")
        hyp = as_ids(hyp_ids, "hyp_ids")
        gxy = as_points(gt_xy, "gt_xy", gt.size, "gt_ids")
        hxy = as_points(hyp_xy, "hyp_xy", hyp.size, "hyp_ids")
        if gt.size and hyp.size:
            if gxy.shape[1] != hxy.shape[1]:
                raise ValueError(
                    "gt_xy and hyp_xy must have the same number of coordinates; "
                    f"got {gxy.shape[1]} and {hxy.shape[1]}"
                )
            dist = pairwise_distances(gxy, hxy)
            dist[dist > self._max_distance_m] = np.inf
        else:
            dist = np.empty((gt.size, hyp.size), dtype=np.float64)
        self._add_frame(gt, hyp, dist, time_s)

    def update_missing_frame(
        self, gt_ids: ArrayLike, gt_xy: ArrayLike, time_s: float | None = None
    ) -> None:
        """Add a frame for which the tracker produced no output at all.

        Every ground-truth object present is a miss; this is the same as :meth:`update`
        with zero hypotheses, kept separate so dropped tracker frames are explicit.

        Parameters
        ----------
        gt_ids : sequence of int, length n
            Ground-truth ids present in the frame, unique within the frame.
        gt_xy : array_like, shape (n, 2) or (n, 3)
            Ground-truth positions in metres (validated, not otherwise used).
        time_s : float, optional
            Time of the frame, seconds (see :meth:`update`).

        Raises
        ------
        ValueError
            If the ids or positions are invalid (see :meth:`update`).
        """
        gt = as_ids(gt_ids, "gt_ids")
        as_points(gt_xy, "gt_xy", gt.size, "gt_ids")
        self._add_frame(gt, EMPTY_IDS, np.empty((gt.size, 0), dtype=np.float64), time_s)

    def _add_frame(
        self,
        gt: NDArray[np.int64],
        hyp: NDArray[np.int64],
        dist: NDArray[np.float64],
        time_s: float | None,
    ) -> None:
        """Match one validated frame and record its events."""
        n, m = dist.shape
        gt_match = np.full(n, -1, dtype=np.int64)
        hyp_taken = np.zeros(m, dtype=bool)
        matched_distances = 0.0
        matches = 0
        if n and m:
            gated = np.isfinite(dist)
            gt_list = gt.tolist()
            hyp_list = hyp.tolist()
            # 1. keep each object's most recent correspondence when still possible
            if self._last_hyp:
                column = {h: j for j, h in enumerate(hyp_list)}
                for i, o in enumerate(gt_list):
                    previous = self._last_hyp.get(o)
                    j = -1 if previous is None else column.get(previous, -1)
                    if j >= 0 and not hyp_taken[j] and gated[i, j]:
                        gt_match[i] = j
                        hyp_taken[j] = True
                        matched_distances += float(dist[i, j])
                        matches += 1
            # 2. assign the rest: most pairs within the gate, then least total distance
            free_rows = np.flatnonzero(gt_match < 0)
            free_cols = np.flatnonzero(~hyp_taken)
            if free_rows.size and free_cols.size:
                rr, cc = max_matching_min_cost(dist[np.ix_(free_rows, free_cols)])
                for i, j in zip(free_rows[rr].tolist(), free_cols[cc].tolist(), strict=True):
                    o, h = gt_list[i], hyp_list[j]
                    previous = self._last_hyp.get(o)
                    if previous is not None and previous != h:
                        self._switches += 1
                    self._last_hyp[o] = h
                    gt_match[i] = j
                    hyp_taken[j] = True
                    matched_distances += float(dist[i, j])
                    matches += 1
            vi, vj = np.nonzero(gated)
            self._pair_gt.append(gt[vi])
            self._pair_hyp.append(hyp[vj])
            if matches and matches < m:
                t = self._frames * self._frame_period_s if time_s is None else float(time_s)
                self._duplicates.add_frame(t, gt, hyp, dist, gt_match >= 0, hyp_taken)
        t_frame = self._frames * self._frame_period_s if time_s is None else float(time_s)
        matched_hyp = np.full(n, -1, dtype=np.int64)
        matched_hyp[gt_match >= 0] = hyp[gt_match[gt_match >= 0]]
        self._returns.add_frame(t_frame, gt, matched_hyp)
        self._frames += 1
        self._matches += matches
        self._distance_sum += matched_distances
        self._fn += n - matches
        self._fp += m - matches
        self._gt_ids.append(gt)
        self._gt_matched.append(gt_match >= 0)
        self._hyp_ids.append(hyp)

    def compute(self) -> MotMetrics:
        """Compute the metrics over all frames added so far.

        Returns
        -------
        MotMetrics
            CLEAR MOT counts and ratios, track-level counts and identity measures.
        """
        gt_all = np.concatenate(self._gt_ids) if self._gt_ids else EMPTY_IDS
        matched_all = (
            np.concatenate(self._gt_matched) if self._gt_matched else np.zeros(0, dtype=bool)
        )
        hyp_all = np.concatenate(self._hyp_ids) if self._hyp_ids else EMPTY_IDS
        gt_objects = int(gt_all.size)
        hyp_objects = int(hyp_all.size)

        gt_uniq, gt_inv = np.unique(gt_all, return_inverse=True)
        hyp_uniq, hyp_inv = np.unique(hyp_all, return_inverse=True)
        gt_frames = np.bincount(gt_inv, minlength=gt_uniq.size)
        hyp_frames = np.bincount(hyp_inv, minlength=hyp_uniq.size)

        ratio = np.bincount(gt_inv, weights=matched_all, minlength=gt_uniq.size)
        if gt_uniq.size:
            ratio = ratio / gt_frames
        mostly_tracked = int(np.count_nonzero(ratio >= _MOSTLY_TRACKED_RATIO))
        mostly_lost = int(np.count_nonzero(ratio < _MOSTLY_LOST_RATIO))
        partially_tracked = int(gt_uniq.size) - mostly_tracked - mostly_lost

        fragmentations = _count_fragmentations(gt_inv, matched_all)
        pair_gt = np.concatenate(self._pair_gt) if self._pair_gt else EMPTY_IDS
        pair_hyp = np.concatenate(self._pair_hyp) if self._pair_hyp else EMPTY_IDS
        idtp = identity_true_positives(gt_uniq, gt_frames, hyp_uniq, hyp_frames, pair_gt, pair_hyp)

        duplicates, duplicate_s = self._duplicates.episodes()
        returns, returns_kept = self._returns.returns()
        matches = self._matches
        errors = self._fn + self._fp + self._switches
        return MotMetrics(
            mota=1.0 - errors / gt_objects if gt_objects else math.nan,
            motp=self._distance_sum / matches if matches else math.nan,
            idf1=_ratio(2 * idtp, gt_objects + hyp_objects),
            idp=_ratio(idtp, hyp_objects),
            idr=_ratio(idtp, gt_objects),
            precision=_ratio(matches, hyp_objects),
            recall=_ratio(matches, gt_objects),
            fp=self._fp,
            fn=self._fn,
            id_switches=self._switches,
            fragmentations=fragmentations,
            matches=matches,
            frames=self._frames,
            gt_objects=gt_objects,
            hyp_objects=hyp_objects,
            gt_tracks=int(gt_uniq.size),
            hyp_tracks=int(hyp_uniq.size),
            mostly_tracked=mostly_tracked,
            partially_tracked=partially_tracked,
            mostly_lost=mostly_lost,
            duplicates=duplicates,
            duplicate_s=duplicate_s,
            returns=returns,
            returns_kept=returns_kept,
        )


def _count_fragmentations(gt_inv: NDArray[np.intp], matched: NDArray[np.bool_]) -> int:
    """Count matched-to-missed transitions followed by a later match, per gt track.

    ``gt_inv`` gives the dense track index of every ground-truth occurrence in frame
    order and ``matched`` whether that occurrence was matched. Frames in which the
    object is absent are skipped, as in py-motmetrics.
    """
    if gt_inv.size < 2:
        return 0
    order = np.argsort(gt_inv, kind="stable")  # grouped by track, frame order kept
    track = gt_inv[order]
    hit = matched[order]
    position = np.arange(track.size)
    starts = np.flatnonzero(np.r_[True, track[1:] != track[:-1]])
    last_hit = np.maximum.reduceat(np.where(hit, position, -1), starts)
    last_hit_of = np.repeat(last_hit, np.diff(np.r_[starts, track.size]))
    begins_gap = (track[1:] == track[:-1]) & hit[:-1] & ~hit[1:] & (position[1:] < last_hit_of[1:])
    return int(np.count_nonzero(begins_gap))


def _ratio(numerator: float, denominator: float) -> float:
    """Divide, returning NaN for a zero denominator."""
    return float(numerator) / denominator if denominator else math.nan
