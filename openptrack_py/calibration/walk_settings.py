"""Tuning of the calibration from one walking person: one settings record for every stage.

Its single role is to hold the thresholds, in one frozen record, of every stage of
:mod:`openptrack_py.calibration.walk`: the walker's tracklets and smoothing
(:mod:`~openptrack_py.calibration.walk_tracks`); the speed-profile clock offsets and the
pairwise RANSAC (:mod:`~openptrack_py.calibration.walk_pairs`; Zhang et al., children
behavior tracking, §2.2); the joint robust least squares
(:mod:`~openptrack_py.calibration.walk_solve`); the disagreement and the refinement's
cross-validated acceptance (:mod:`~openptrack_py.calibration.walk_measure`,
:mod:`~openptrack_py.calibration.walk_result`; Munaro et al., OpenPTrack, §4.3).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["WalkSettings"]


@dataclass(frozen=True)
class WalkSettings:
    """Tuning of the walk calibration (the defaults suit 30 Hz depth sensors, one walker).

    Parameters
    ----------
    min_detections : int
        Each sensor needs at least this many detections of the walker.
    min_confidence : float
        Detections below this confidence are ignored.
    link_gate_m : float
        A detection joins a tracklet if within this distance of its last position (plus
        ``max_speed_m_s`` times the time since).
    max_speed_m_s : float
        Fastest walking speed expected.
    max_gap_s : float
        A tracklet ends after this long without a detection.
    min_tracklet_s, min_tracklet_points : float, int
        Shorter tracklets (transient false positives, split blobs) are dropped.
    min_tracklet_motion_m : float
        Tracklets that never move this far from their median position (decoys, static
        clutter) are dropped.
    smooth_half_window_s : float
        Half width of the local quadratic fit that smooths a trajectory.
    max_interp_gap_s : float
        A trajectory is interpolated only between samples at most this far apart.
    max_clock_offset_s : float
        Largest clock offset between two sensors searched by the speed-profile
        cross-correlation.
    speed_grid_s : float
        Sampling step of the speed profiles.
    ransac_threshold_m : float
        Inlier distance of the pairwise RANSAC.
    ransac_iterations : int
        Hypotheses per RANSAC.
    min_pair_matches : int
        Two sensors overlap if RANSAC keeps at least this many time-matched detections.
    min_extent_m : tuple of float
        A pair's matched positions must span at least this much along their major and
        minor principal axes (5th to 95th percentile), metres, to fix the pair's
        transform and clock offset on their own.
    loss : str
        Robust loss of the joint least squares (``scipy.optimize.least_squares``).
    loss_scale_m : float
        Its scale: residuals beyond it count less than quadratically.
    max_gate_m : float
        Largest residual a match may keep in the joint solve's re-gating.
    solve_rounds : int
        Solve, re-match and re-gate this many times.
    bin_s : float
        Time bin of the disagreement, seconds.
    cv_block_s : float
        Length of the alternating time blocks of the refinement's two cross-validation
        folds, seconds (a multiple of ``bin_s``).
    min_improvement : float
        A refinement is accepted only if it cuts the held-out disagreement by at least
        this fraction.
    min_significance : float
        ... and only if the cut is this many standard errors below zero: the mean over
        the pairs' cross-validation blocks of the log ratio of held-out to current
        disagreement, per time bin (a one-sided t test).
    seed : int
        Seed of the RANSAC sampling.
    """

    min_detections: int = 100
    min_confidence: float = 0.3
    link_gate_m: float = 0.5
    max_speed_m_s: float = 2.5
    max_gap_s: float = 0.5
    min_tracklet_s: float = 1.0
    min_tracklet_points: int = 10
    min_tracklet_motion_m: float = 0.5
    smooth_half_window_s: float = 0.35
    max_interp_gap_s: float = 0.2
    max_clock_offset_s: float = 1.0
    speed_grid_s: float = 0.02
    ransac_threshold_m: float = 0.4
    ransac_iterations: int = 400
    min_pair_matches: int = 60
    min_extent_m: tuple[float, float] = (1.5, 0.5)
    loss: str = "soft_l1"
    loss_scale_m: float = 0.1
    max_gate_m: float = 0.6
    solve_rounds: int = 3
    bin_s: float = 1.0
    cv_block_s: float = 10.0
    min_improvement: float = 0.05
    min_significance: float = 2.0
    seed: int = 0
