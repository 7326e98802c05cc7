"""A solve's outcome: the disagreement before and after, the reports, the acceptance.

Its single role is to turn a solved calibration into a :class:`WalkCalibration`: the
disagreement (:mod:`~openptrack_py.calibration.walk_measure`) with the starting and the
solved poses and offsets over one common set of matches, what each pair and each sensor
contributed, and for a refinement the cross-validated acceptance of Munaro et al.,
OpenPTrack, §4.3 (poses already close are improved from a walk and kept only if the
sensors then agree better): each half of the walk (alternating time blocks) is measured
with the solution fitted to the other half, and the refinement is kept only if that
held-out disagreement falls by ``WalkSettings.min_improvement`` and significantly so, so
that fitting the walk's noise never passes for a gain.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from openptrack_py.calibration.walk_measure import (
    Disagreement,
    _Distances,
    _distances,
    _significance,
    _summary,
    _validity,
)
from openptrack_py.calibration.walk_pairs import _Pair
from openptrack_py.calibration.walk_settings import WalkSettings
from openptrack_py.calibration.walk_solve import _Block, _blocks_from_pairs, _residuals
from openptrack_py.calibration.walk_tracks import Pose2D, _Walker, _wrap_deg

__all__ = ["PairReport", "Spread", "WalkCalibration"]


@dataclass(frozen=True)
class PairReport:
    """What one pair of sensors contributed.

    Parameters
    ----------
    sensors : tuple of str
        The two sensors.
    candidates : int
        Time-matched detections of the first sensor (against the second's trajectory)
        at the pair's first clock offset.
    inliers : int
        Of those, kept by RANSAC (0: the views do not overlap).
    used : int
        Time-matched pairs of detections (both directions) in the final joint solve.
    extent_m : tuple of float
        Span of the inliers along their major and minor principal axes, metres.
    coarse_lag_s : float
        The pair's first clock offset (second sensor's minus first's).
    residual_m : float
        Median distance between the pair's matched detections after the solve, metres
        (nan if unused).
    """

    sensors: tuple[str, str]
    candidates: int
    inliers: int
    used: int
    extent_m: tuple[float, float]
    coarse_lag_s: float
    residual_m: float


@dataclass(frozen=True)
class Spread:
    """How far one sensor's solutions from the two halves of the walk lie apart, halved.

    Each half (alternating blocks of ``WalkSettings.cv_block_s``) is solved on its own;
    with errors of the same size in each, half their difference has the standard
    deviation of the whole walk's solution (a delete-half jackknife). It sees the
    second-long detector errors that a covariance from the residuals misses, but it is
    one draw per sensor: the true error is below it about half the time and below three
    times it about four times in five (nine in ten for the position, a distance in two
    dimensions). Relative to the sensor the solve holds in place (whose spread is 0):
    the reference of a walk, the fixed sensor or the one with most matches of a
    refinement.

    Parameters
    ----------
    position_m : float
        Floor position, metres.
    yaw_deg : float
        Heading, degrees.
    clock_s : float
        Clock offset, seconds.
    """

    position_m: float
    yaw_deg: float
    clock_s: float


def _spread(ids: Sequence[str], halves: Sequence[np.ndarray]) -> dict[str, Spread]:
    """Per sensor, half the difference between two solved states."""
    a, b = halves
    turn = np.angle(np.exp(1j * (a[:, 2] - b[:, 2])))
    return {
        sid: Spread(
            float(np.hypot(*(a[k, :2] - b[k, :2])) / 2),
            float(abs(math.degrees(turn[k])) / 2),
            float(abs(a[k, 3] - b[k, 3]) / 2),
        )
        for k, sid in enumerate(ids)
    }


@dataclass(frozen=True)
class WalkCalibration:
    """The result of :func:`calibrate_walk` or :func:`refine_walk`.

    Parameters
    ----------
    method : {"walk", "refinement"}
        Which procedure.
    anchor : str
        What keeps the world frame: a sensor id (its pose and clock are kept) or
        ``"mean"`` (the network moved as one body to keep the walk where it was).
    poses : Mapping of str to Pose2D
        Each sensor's floor pose in the world (the current ones when refused).
    clock_offsets_s : Mapping of str to float
        Each sensor's clock minus the reference clock, seconds: subtract from its stamps.
    residual_m : Mapping of str to float
        Per sensor, the median distance of its matched detections to the other sensors'
        after the solve, metres.
    pairs : tuple of PairReport
        Every pair of sensors.
    before : Disagreement
        With the starting poses and offsets (refinement: the current calibration;
        walk: the rough guess if given, else the pairwise chain).
    after : Disagreement
        With the solved ones.
    accepted : bool
        Whether ``poses`` are the solved ones (a refinement that does not cut the
        held-out disagreement by ``WalkSettings.min_improvement`` is refused).
    note : str
        Why it was refused, or empty.
    solved_poses : Mapping of str to Pose2D
        The solved poses, accepted or not.
    solved_clock_offsets_s : Mapping of str to float
        The solved offsets, accepted or not.
    held_out : Disagreement, optional
        The disagreement on each half of the walk (alternating blocks of
        ``WalkSettings.cv_block_s``) with the solution fitted to the other half; what a
        refinement's acceptance is judged on, so that fitting the noise of the walk is
        no gain.
    spread : Mapping of str to Spread
        Per sensor, half the difference between the solutions fitted to the two halves
        of the walk: an estimate of the solved pose's and clock's error from the walk
        alone (see :class:`Spread`); empty if the halves were not solved.
    """

    method: Literal["walk", "refinement"]
    anchor: str
    poses: Mapping[str, Pose2D]
    clock_offsets_s: Mapping[str, float]
    residual_m: Mapping[str, float]
    pairs: tuple[PairReport, ...]
    before: Disagreement
    after: Disagreement
    accepted: bool
    note: str = ""
    solved_poses: Mapping[str, Pose2D] = field(default_factory=dict)
    solved_clock_offsets_s: Mapping[str, float] = field(default_factory=dict)
    held_out: Disagreement | None = None
    spread: Mapping[str, Spread] = field(default_factory=dict)

    @property
    def improvement(self) -> float:
        """``before / after`` of the binned disagreement (inf when after is 0)."""
        if self.after.binned_m <= 0.0:
            return math.inf
        return self.before.binned_m / self.after.binned_m


def _unpack(ids: Sequence[str], state: np.ndarray) -> tuple[dict[str, Pose2D], dict[str, float]]:
    poses = {
        i: Pose2D(float(state[k, 0]), float(state[k, 1]), _wrap_deg(math.degrees(state[k, 2])))
        for k, i in enumerate(ids)
    }
    return poses, {i: float(state[k, 3]) for k, i in enumerate(ids)}


def _reports(
    ids: Sequence[str],
    pairs: Sequence[_Pair],
    blocks: Sequence[_Block],
    residuals: Sequence[np.ndarray],
) -> tuple[tuple[PairReport, ...], dict[str, float]]:
    used: dict[int, list[np.ndarray]] = {}
    per_sensor: dict[int, list[np.ndarray]] = {}
    for b, r in zip(blocks, residuals, strict=True):
        d = np.linalg.norm(r, axis=1)
        used.setdefault(b.pair, []).append(d)
        per_sensor.setdefault(b.i, []).append(d)
        per_sensor.setdefault(b.j, []).append(d)
    reports = []
    for n, p in enumerate(pairs):
        d = np.concatenate(used[n]) if n in used else np.zeros(0)
        reports.append(
            PairReport(
                sensors=(p.i, p.j),
                candidates=len(p.rows),
                inliers=p.count,
                used=len(d),
                extent_m=p.extent,
                coarse_lag_s=p.lag,
                residual_m=float(np.median(d)) if len(d) else float("nan"),
            )
        )
    residual = {
        i: float(np.median(np.concatenate(per_sensor[k]))) if k in per_sensor else float("nan")
        for k, i in enumerate(ids)
    }
    return tuple(reports), residual


def _held_out(
    walkers: Sequence[_Walker],
    measured: Sequence[_Block],
    start: np.ndarray,
    valid: Sequence[np.ndarray],
    before_d: _Distances,
    held_out: Sequence[np.ndarray],
    s: WalkSettings,
) -> tuple[Disagreement, float]:
    """The held-out disagreement and the t statistic of its change from ``before_d``.

    ``held_out[f]`` is the solution fitted on fold ``1 - f``; each fold is measured with
    it, bin for bin against the current calibration (binned on its clocks).
    """
    parts = [_distances(walkers, measured, st, valid, s, clock=start) for st in held_out]
    ratio = np.zeros(len(before_d.binned))
    for f, part in enumerate(parts):
        mine = before_d.binned_fold == f
        ratio[mine] = np.log(part.binned[mine] / np.maximum(before_d.binned[mine], 1e-9))
    binned = np.concatenate([p.binned[p.binned_fold == f] for f, p in enumerate(parts)])
    frames = np.concatenate([p.frames[p.frames_fold == f] for f, p in enumerate(parts)])
    return _summary(binned, frames), _significance(ratio, before_d.binned_block)


def _verdict(
    before: Disagreement,
    after: Disagreement,
    held: Disagreement | None,
    gain: float,
    s: WalkSettings,
) -> tuple[bool, str]:
    """Whether a refinement is accepted, and if not the note saying why.

    Judged on the held-out disagreement when there is one (else on ``after``): it must
    fall by ``min_improvement`` of ``before``, and its fall must be significant (``gain``
    at most ``-min_significance``).
    """
    judged = held if held is not None else after
    bar = (1.0 - s.min_improvement) * before.binned_m
    if not (judged.binned_m <= bar):
        return False, (
            f"refused: on the parts of the walk it was not fitted to, the disagreement "
            f"would go from {before.binned_m:.3f} m to {judged.binned_m:.3f} m (it must "
            f"fall by {100 * s.min_improvement:.0f}% or more); the current calibration "
            "is kept"
        )
    if held is not None and not gain <= -s.min_significance:
        return False, (
            f"refused: on the parts of the walk it was not fitted to, the disagreement "
            f"would go from {before.binned_m:.3f} m to {judged.binned_m:.3f} m, but "
            f"that is within the walk's own scatter (t = {gain:.1f}, must be "
            f"-{s.min_significance:g} or lower); the current calibration is kept"
        )
    return True, ""


def _finish(
    method: Literal["walk", "refinement"],
    anchor: str,
    ids: Sequence[str],
    walkers: Sequence[_Walker],
    pairs: Sequence[_Pair],
    index: Mapping[str, int],
    start: np.ndarray,
    solved: np.ndarray,
    final_blocks: Sequence[_Block],
    s: WalkSettings,
    *,
    refuse: bool,
    held_out: Sequence[np.ndarray] | None = None,
) -> WalkCalibration:
    """The result of a solve from ``start`` to ``solved``.

    With ``refuse``, the solution is kept only if :func:`_verdict` accepts it;
    ``held_out`` as for :func:`_held_out`: the held-out disagreement and the spread.
    """
    overlapping = [p for p in pairs if p.count >= s.min_pair_matches]
    measured = _blocks_from_pairs(walkers, index, overlapping)
    states = [start, solved, *(held_out or ())]
    valid = _validity(walkers, measured, states)
    before_d = _distances(walkers, measured, start, valid, s)
    before, after = before_d.summary(), _distances(walkers, measured, solved, valid, s).summary()
    held: Disagreement | None = None
    gain = math.nan
    if held_out is not None:
        held, gain = _held_out(walkers, measured, start, valid, before_d, held_out, s)
    res, _ = _residuals(final_blocks, walkers, solved)
    reports, residual = _reports(ids, pairs, final_blocks, res)
    solved_poses, solved_offsets = _unpack(ids, solved)
    accepted, note = _verdict(before, after, held, gain, s) if refuse else (True, "")
    poses, offsets = _unpack(ids, solved if accepted else start)
    return WalkCalibration(
        method=method,
        anchor=anchor,
        poses=poses,
        clock_offsets_s=offsets,
        residual_m=residual,
        pairs=reports,
        before=before,
        after=after,
        accepted=accepted,
        note=note,
        solved_poses=solved_poses,
        solved_clock_offsets_s=solved_offsets,
        held_out=held,
        spread=_spread(ids, held_out) if held_out is not None else {},
    )
