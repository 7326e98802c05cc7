"""Calibration from one walking person: every sensor's floor pose and clock from a walk.

One person walks through the space while every sensor's detector reports them on the
floor. A sensor's calibration on the floor is a rigid 2-D transform (``x``, ``y``,
``yaw``) from its own floor frame (origin at the camera's foot, ``x`` along the optical
axis projected on the floor, ``y`` to the left; :meth:`GroundPlane.ground_from_camera
<openptrack_py.detection.ground.GroundPlane.ground_from_camera>`) to the world, plus a
clock offset (its stamps are the true time plus the offset). Two procedures share one
solver:

* :func:`calibrate_walk` — no checkerboard, no pose guess (Zhang et al., "Children
  Behavior Tracking and Personal Identification By Multiple Kinect Sensors", §2.2: a
  transform from one walking person's positions seen by two sensors, RANSAC over the
  correspondences). For every pair of sensors, a first clock offset from the
  cross-correlation of their walking-speed profiles (``|v(t)|`` does not depend on the
  unknown transform), a RANSAC rigid transform over time-matched detections (one
  sensor's smoothed trajectory interpolated at the other's stamps; false positives
  fall out as outliers), a graph of the overlapping pairs, poses and offsets chained
  from the reference sensor along its maximum spanning tree, then the joint solve;
* :func:`refine_walk` — the refinement of Munaro et al., "OpenPTrack: Open Source
  Multi-Camera Calibration and People Tracking for RGB-D Camera Networks", §4.3: poses
  already close (a checkerboard calibration) are improved from the walk by the same
  joint solve started from them, and kept only if the sensors then agree better on
  the parts of the walk the solve did not see (two-fold cross-validation over
  alternating 10 s blocks), so that fitting the walk's noise never passes for a gain.

The **joint solve** is one robust least squares (``scipy.optimize.least_squares``,
soft-L1 loss) over every sensor's ``(x, y, yaw, clock offset)`` and every time-matched
pair of detections of every overlapping pair of sensors, in both directions:
``R_i p_i(t) + T_i - R_j q_j(t - o_i + o_j) - T_j``, where ``q_j`` is sensor ``j``'s
smoothed trajectory interpolated at the stamp of the same true time (smoothed, not raw:
interpolating between raw noisy samples is least noisy halfway between them, which pulls
the clock offsets towards putting one sensor's frames halfway between the other's; a
smoothed trajectory is equally noisy wherever it is interpolated). Matches are
re-made and outliers re-gated with the solved offsets and poses, and solved again.
Only offset differences are observable: the reference sensor's (or the fixed one's, or
the mean) sets the time origin, as its pose sets the world frame.

**Disagreement** is how far apart the sensors put the walker at the same instant, in
the world frame, over the time-matched detections the pairwise RANSAC kept (a set that
does not depend on the poses being compared): the median, over sensor pairs and
one-second bins of true time, of the length of the mean difference between one
sensor's detections and the other's linearly interpolated raw detections (time-binned
as OpenPTrack's refinement bins its detections; per-frame detector noise averages out
within a bin, what stays is each sensor's persistent error and the calibration's).
The per-frame median of those distances (``raw``) is reported too.

Only the walker may be in the space during the walk; clutter, decoys and split blobs
are tolerated: each sensor's detections are linked into tracklets, static and
short-lived ones are dropped, and RANSAC and the robust loss reject what is left.

This module is the entry point (:func:`calibrate_walk`, :func:`refine_walk`, and the
public types re-exported); the work is split by role into sibling modules:
:mod:`~openptrack_py.calibration.walk_settings` (the tuning),
:mod:`~openptrack_py.calibration.walk_tracks` (poses, tracks, one sensor's walker and
time matching), :mod:`~openptrack_py.calibration.walk_pairs` (clock offsets, pairwise
RANSAC, the pair graph and chaining), :mod:`~openptrack_py.calibration.walk_solve` (the
joint solve), :mod:`~openptrack_py.calibration.walk_measure` (the disagreement) and
:mod:`~openptrack_py.calibration.walk_result` (reports and the cross-validated
acceptance).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Literal

import numpy as np

from openptrack_py.calibration.walk_measure import Disagreement
from openptrack_py.calibration.walk_pairs import _all_pairs, _chain, _check_graph, _Pair
from openptrack_py.calibration.walk_result import PairReport, Spread, WalkCalibration, _finish
from openptrack_py.calibration.walk_settings import WalkSettings
from openptrack_py.calibration.walk_solve import _anchor_mean, _Block, _solve
from openptrack_py.calibration.walk_tracks import (
    Pose2D,
    WalkTrack,
    _Walker,
    _walker,
    floor_from_world,
    report_in_world,
    tracks_from_batches,
)
from openptrack_py.errors import CalibrationError

__all__ = [
    "Disagreement",
    "PairReport",
    "Pose2D",
    "Spread",
    "WalkCalibration",
    "WalkSettings",
    "WalkTrack",
    "calibrate_walk",
    "floor_from_world",
    "refine_walk",
    "report_in_world",
    "tracks_from_batches",
]


def _prepare(
    tracks: Sequence[WalkTrack], s: WalkSettings
) -> tuple[list[_Walker], dict[str, int], float]:
    ids = [t.sensor_id for t in tracks]
    if len(ids) < 2:
        raise CalibrationError(f"walk: need at least two sensors (received {len(ids)})")
    dupes = sorted({i for i in ids if ids.count(i) > 1})
    if dupes:
        raise CalibrationError(f"walk: sensor {', '.join(dupes)} has more than one track")
    nonempty = [t.stamps[0] for t in tracks if len(t)]
    origin = float(min(nonempty)) if nonempty else 0.0
    walkers = [_walker(t, origin, s) for t in tracks]
    return walkers, {w: k for k, w in enumerate(ids)}, origin


def _state(
    ids: Sequence[str], poses: Mapping[str, Pose2D], offsets: Mapping[str, float]
) -> np.ndarray:
    return np.array(
        [[poses[i].x, poses[i].y, poses[i].yaw, offsets.get(i, 0.0)] for i in ids], dtype=float
    )


def _refinement_walkers(
    tracks: Sequence[WalkTrack],
    poses: Mapping[str, Pose2D],
    fixed: str | None,
    frame: str,
    s: WalkSettings,
) -> tuple[list[str], list[_Walker], dict[str, int]]:
    """The refinement's arguments checked, and every sensor's walker in its floor frame."""
    ids = [t.sensor_id for t in tracks]
    missing = [i for i in ids if i not in poses]
    if missing:
        raise CalibrationError(f"refinement: no current pose for sensor {', '.join(missing)}")
    if fixed is not None and fixed not in ids:
        raise CalibrationError(
            f"refinement: fixed sensor {fixed!r} is not among the sensors ({', '.join(ids)})"
        )
    if frame not in ("world", "floor"):
        raise CalibrationError(f"refinement: frame must be world or floor (received {frame!r})")
    floor = (
        tracks
        if frame == "floor"
        else [t.transformed(poses[t.sensor_id].inverse()) for t in tracks]
    )
    walkers, index, _ = _prepare(floor, s)
    return ids, walkers, index


def _held_sensor(ids: Sequence[str], pairs: Sequence[_Pair], fixed: str | None) -> str:
    """The sensor kept in place by the solve: ``fixed``, else the one with most inliers."""
    if fixed is not None:
        return fixed
    counts = {i: 0 for i in ids}
    for p in pairs:
        counts[p.i] += p.count
        counts[p.j] += p.count
    return max(ids, key=lambda i: counts[i])


def _refine_solve(
    walkers: Sequence[_Walker],
    pairs: Sequence[_Pair],
    index: Mapping[str, int],
    current: np.ndarray,
    free: Sequence[bool],
    anchor_mean: bool,
    s: WalkSettings,
) -> tuple[np.ndarray, list[_Block], list[np.ndarray]]:
    """The refinement's solve on the whole walk, and on each cross-validation fold."""
    solved, blocks = _solve(walkers, pairs, index, current, free, free, s)
    # fold f measured with the solution fitted to the other fold (no anchoring needed:
    # the disagreement does not depend on where the network as a whole stands)
    held_out = [_solve(walkers, pairs, index, current, free, free, s, 1 - f)[0] for f in (0, 1)]
    if anchor_mean:
        solved = _anchor_mean(walkers, current, solved)
    return solved, blocks, held_out


def calibrate_walk(
    tracks: Sequence[WalkTrack],
    *,
    reference: str | None = None,
    reference_pose: Pose2D | None = None,
    initial_poses: Mapping[str, Pose2D] | None = None,
    settings: WalkSettings | None = None,
) -> WalkCalibration:
    """Calibrate sensors with no checkerboard from one person's walk.

    Parameters
    ----------
    tracks : sequence of WalkTrack
        Each sensor's detections in its own floor frame, stamps on its own clock.
    reference : str, optional
        The sensor whose floor frame (placed at ``reference_pose``) is the world and whose
        clock is the reference; the first track's if omitted.
    reference_pose : Pose2D, optional
        Where the reference sensor's floor frame is in the world; the identity (the world
        is its floor frame) if omitted.
    initial_poses : Mapping of str to Pose2D, optional
        A rough guess of every sensor's pose. The result is then moved as one rigid body
        (and its clocks by their mean) to agree best with the guess, which thus sets the
        world frame; the reference and ``reference_pose`` are then ignored. The
        disagreement ``before`` is the guess's.
    settings : WalkSettings, optional
        Tuning.

    Returns
    -------
    WalkCalibration
        Always accepted; its ``spread`` is half the difference between the solutions
        fitted to the walk's two halves.

    Raises
    ------
    CalibrationError
        For too few detections from a sensor, sensors whose views never overlap during
        the walk (naming the groups), or a walk that covers too little of a pair's common
        view (naming the pair and the extent).
    """
    s = settings or WalkSettings()
    walkers, index, _ = _prepare(tracks, s)
    ids = list(index)
    ref = ids[0] if reference is None else reference
    if ref not in index:
        raise CalibrationError(
            f"walk: reference {ref!r} is not among the sensors ({', '.join(ids)})"
        )
    if initial_poses is not None:
        missing = [i for i in ids if i not in initial_poses]
        if missing:
            raise CalibrationError(f"walk: initial_poses has no pose for {', '.join(missing)}")
    pairs = _all_pairs(walkers, s, None)
    _check_graph(ids, pairs, s)
    poses, offsets = _chain(ids, pairs, ref, reference_pose or Pose2D(), s)
    chained = _state(ids, poses, offsets)
    free_pose = [i != ref for i in ids]
    solved, blocks = _solve(walkers, pairs, index, chained, free_pose, free_pose, s)
    # each half of the walk solved on its own: how far they differ is the spread
    halves = [
        _solve(walkers, pairs, index, chained, free_pose, free_pose, s, 1 - f)[0] for f in (0, 1)
    ]
    start, anchor = chained, ref
    if initial_poses is not None:
        start = _state(ids, initial_poses, {})
        solved = _anchor_mean(walkers, start, solved)
        anchor = "mean"
    return _finish(
        "walk", anchor, ids, walkers, pairs, index, start, solved, blocks, s,
        refuse=False, held_out=halves,
    )  # fmt: skip


def refine_walk(
    tracks: Sequence[WalkTrack],
    poses: Mapping[str, Pose2D],
    *,
    clock_offsets_s: Mapping[str, float] | None = None,
    fixed: str | None = None,
    frame: Literal["world", "floor"] = "world",
    settings: WalkSettings | None = None,
) -> WalkCalibration:
    """Refine a calibration from one person's walk; keep it only if sensors agree better.

    The joint solve starts from ``poses`` (and ``clock_offsets_s``). The world frame is
    kept in one of two ways:

    * ``fixed`` names a sensor: its pose and clock stay as they are (choose the sensor
      the world was defined from, e.g. the checkerboard calibration's reference);
    * ``fixed=None`` (default): the mean correction is anchored: the refined network is
      moved as one rigid body so that the walker's detections stay, in the least-squares
      sense, where the current calibration put them, and the clocks are shifted by the
      mean of their changes. Zones and anything else placed in the world stay valid.

    Parameters
    ----------
    tracks : sequence of WalkTrack
        Each sensor's detections: in the world through its current pose (``frame =
        "world"``, what calibrated sensors publish) or in its floor frame (``"floor"``).
    poses : Mapping of str to Pose2D
        The current floor poses in the world.
    clock_offsets_s : Mapping of str to float, optional
        The current clock offsets (each sensor's clock minus the reference); 0 if omitted.
    fixed : str, optional
        The sensor whose pose and clock are kept; the mean anchor if omitted.
    frame : {"world", "floor"}
        Which frame ``tracks`` are in.
    settings : WalkSettings, optional
        Tuning.

    Returns
    -------
    WalkCalibration
        ``accepted`` only if the held-out disagreement (each half of the walk, in
        alternating blocks of ``settings.cv_block_s``, measured with the solution fitted
        to the other half) is at least ``settings.min_improvement`` below the current
        one; otherwise ``poses`` and ``clock_offsets_s`` are the current ones and
        ``note`` says why.

    Raises
    ------
    CalibrationError
        As :func:`calibrate_walk`; also for a sensor without a current pose or an unknown
        ``fixed`` sensor.
    """
    s = settings or WalkSettings()
    ids, walkers, index = _refinement_walkers(tracks, poses, fixed, frame, s)
    current = _state(ids, poses, clock_offsets_s or {})
    pairs = _all_pairs(walkers, s, current)
    _check_graph(ids, pairs, s)
    held = _held_sensor(ids, pairs, fixed)
    free = [i != held for i in ids]
    solved, blocks, held_out = _refine_solve(
        walkers, pairs, index, current, free, fixed is None, s
    )
    return _finish(
        "refinement",
        fixed or "mean",
        ids,
        walkers,
        pairs,
        index,
        current,
        solved,
        blocks,
        s,
        refuse=True,
        held_out=held_out,
    )
