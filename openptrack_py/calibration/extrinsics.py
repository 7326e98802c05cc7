"""Multi-sensor extrinsic calibration: every sensor's pose from shared checkerboard views.

The entry point of the procedure of Munaro et al., OpenPTrack (§4): a checkerboard is
moved through the space and seen by pairs of sensors; the sensors' poses are chained
through the views they share, then all camera and board poses are refined together by
minimising the corners' reprojection error, in the manner of bundle adjustment (as
Kalibr and multical do); the world frame comes from the board laid on the floor.

Steps of :func:`calibrate_extrinsics`, each in its own module:

1. **placements** (:mod:`~openptrack_py.calibration.observations`) — views of different
   sensors are of the same board placement when their stamps are within a tolerance of
   the placement's first (``group_placements``); one view per sensor per placement is
   kept.
2. **pose graph** (:mod:`~openptrack_py.calibration.posegraph`) — sensors are nodes, an
   edge's weight is the number of placements both sensors saw (``pair_views``). Sensors
   are connected when linked by edges of at least ``min_shared_views`` (else
   :class:`~openptrack_py.errors.CalibrationError`).
3. **initial poses** (:mod:`~openptrack_py.calibration.posegraph`) — chained from the
   reference sensor along a maximum spanning tree (Prim's algorithm): each tree edge's
   relative pose is the consensus of its shared views'
   ``child_from_board @ board_from_parent``; each placement's board pose is the
   consensus of its views.
4. **global refinement** (:mod:`~openptrack_py.calibration.bundle`) — ``BundleProblem``:
   ``scipy.optimize.least_squares`` over 6 degrees of freedom per sensor (the reference
   fixed, which fixes the gauge; the board's size fixes the scale) and per placement,
   minimising pixel reprojection error of every corner with a Huber loss, a sparse
   Jacobian (a view's residuals depend only on its sensor and its placement) and
   Jacobian-scaled variables; optionally every sensor's pinhole and lens distortion
   too (``refine_intrinsics``: a unit's intrinsics differ from its type's nominal ones,
   and a focal length 2 % off puts a board 2 % too far, which the poses absorb). Then
   outliers go, one at a time per placement and per
   view, and the problem is solved again until none is left (as Kalibr rejects
   corners): views whose RMS error is far above the rest (a corner order flipped, a
   board that bent), then single corners far off the rest (a corner misplaced on a
   foreshortened board). This module runs that loop (:func:`_fit`).
5. **world frame** — from the placement on the floor (its plane is z = 0, its x axis the
   world's, or as placed by ``world_from_floor_board``); else from a given world pose
   of the reference sensor.

The result (:class:`~openptrack_py.calibration.board_result.ExtrinsicCalibration`, with
its :class:`~openptrack_py.calibration.board_result.CalibrationReport`) is in its own
module and re-exported here, as is
:class:`~openptrack_py.calibration.progress.CalibrationProgress`, what a capture loop
(the CLI, a web page) polls while the board is moved.

Pixels are those of an ideal pinhole: undistort corners first
(:func:`openptrack_py.calibration.intrinsics.undistort_corners`), or refine the
intrinsics with the poses (corners a sensor's reported lens undistorted are then put
back where that lens imaged them, and the lens is refined from it).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TypeVar

import numpy as np

from openptrack_py.calibration.board_result import CalibrationReport, ExtrinsicCalibration
from openptrack_py.calibration.bundle import (
    LENS_MODELS,
    BundleProblem,
    corner_outliers,
    solve,
    view_outliers,
)
from openptrack_py.calibration.evidence import REFINE_LEVEL, IntrinsicsEvidence, weigh_intrinsics
from openptrack_py.calibration.intrinsics import distort_corners
from openptrack_py.calibration.observations import (
    BoardObservation,
    Placement,
    check_observations,
    group_placements,
    pair_views,
)
from openptrack_py.calibration.posegraph import board_guesses, chain_sensors, check_connected
from openptrack_py.calibration.progress import CalibrationProgress
from openptrack_py.detection.frame import Intrinsics
from openptrack_py.errors import CalibrationError
from openptrack_py.geometry import invert

T = TypeVar("T")

__all__ = [
    "FLOOR_BOARD_IN_WORLD",
    "CalibrationProgress",
    "CalibrationReport",
    "ExtrinsicCalibration",
    "calibrate_extrinsics",
]

FLOOR_BOARD_IN_WORLD = np.diag([1.0, -1.0, -1.0, 1.0])
"""Default ``world_from_floor_board``: the world origin at the floor board's first inner
corner, world x along the board's x, z up (the board's z points into the floor)."""


# ------------------------------------------------------------------------------- checks


def _check_left(
    observations: Sequence[BoardObservation], sensor_ids: Sequence[str], reject_px: float
) -> None:
    """Raise naming the sensors whose every view was rejected as an outlier."""
    seen = {o.sensor_id for o in observations}
    lost = [s for s in sensor_ids if s not in seen]
    if lost:
        raise CalibrationError(
            "checkerboard calibration: every board view of "
            f"{', '.join(repr(s) for s in lost)} was rejected (reprojection error above "
            f"{reject_px:g} px and four times the median view's): check its intrinsics "
            "and that the board is flat and rigid"
        )


def _world_from_ref(
    fit: _Fit,
    floor_stamp: float | None,
    tolerance_s: float,
    world_from_floor_board: np.ndarray,
    reference_world_from_camera: np.ndarray | None,
) -> tuple[np.ndarray, str]:
    """The world frame: from the floor placement, else the reference sensor's given pose."""
    if floor_stamp is not None:
        ref_from_board = fit.problem.unpack(fit.x)[1]
        for p, placement in enumerate(fit.placements):
            if -tolerance_s <= floor_stamp - placement.stamp <= tolerance_s:
                return world_from_floor_board @ invert(ref_from_board[p]), "floor board"
    if reference_world_from_camera is not None:
        return np.asarray(reference_world_from_camera, dtype=float), "reference pose"
    what = (
        f"no sensor saw the board laid on the floor (at {floor_stamp:.3f} s)"
        if floor_stamp is not None
        else "no floor placement was given"
    )
    raise CalibrationError(
        f"checkerboard calibration: no world frame: {what} and no world pose of the "
        "reference sensor was given"
    )


# -------------------------------------------------------------------------- entry point


def calibrate_extrinsics(
    observations: Sequence[BoardObservation],
    intrinsics: Mapping[str, Intrinsics],
    object_points: np.ndarray,
    *,
    reference: str | None = None,
    floor_stamp: float | None = None,
    world_from_floor_board: np.ndarray | None = None,
    reference_world_from_camera: np.ndarray | None = None,
    tolerance_s: float = 0.5,
    min_shared_views: int = 3,
    huber_px: float = 0.5,
    reject_px: float = 1.0,
    max_evaluations: int = 200,
    refine_intrinsics: bool = False,
    lens: str = "radial",
    refine_level: float | None = REFINE_LEVEL,
) -> ExtrinsicCalibration:
    """Every sensor's pose from checkerboard views (Munaro et al., OpenPTrack, §4).

    Parameters
    ----------
    observations : sequence of BoardObservation
        The board views of all sensors.
    intrinsics : mapping of str to Intrinsics
        Every sensor to calibrate, its pinhole (of undistorted pixels) and the lens its
        corners were undistorted with, if any (as ``detect_board`` reports them).
    object_points : ndarray
        ``(n, 3)`` corners in the board frame (``Checkerboard.object_points``).
    reference : str, optional
        The sensor held fixed during the solve; the first of ``intrinsics`` by default.
    floor_stamp : float, optional
        Stamp of the placement with the board flat on the floor, printed side up.
    world_from_floor_board : ndarray, optional
        Where that board lies in the world (4x4); :data:`FLOOR_BOARD_IN_WORLD` by default.
    reference_world_from_camera : ndarray, optional
        The reference sensor's world pose, used when the floor board was not seen.
    tolerance_s : float
        Largest spread of stamps of one placement's views, seconds.
    min_shared_views : int
        Fewest placements two sensors must share to link them.
    huber_px : float
        Residual beyond which the loss grows linearly, pixels (a good detector's corner
        noise is 0.1-0.2 px).
    reject_px : float
        Views whose RMS error exceeds this and four times the median view's are rejected,
        then corners beyond half this and four times the median corner's; solved again.
    max_evaluations : int
        Cap on residual evaluations per solve.
    refine_intrinsics : bool
        Also solve every sensor's pinhole and lens with the poses, from ``intrinsics``
        under a weak prior, on the corners as seen (:func:`_as_seen`).
    lens : {"radial", "full"}
        The lens terms solved: ``k1, k2`` or OpenCV's five (:mod:`.bundle`'s ``LENS_MODELS``).
    refine_level : float, optional
        Chance of refining a sensor's right intrinsics: a refinement is kept only where
        the views show them wrong (:mod:`.evidence`); ``None``: always kept.

    Returns
    -------
    ExtrinsicCalibration

    Raises
    ------
    CalibrationError
        The board was never found; a sensor never saw it (named); the sensors are not
        connected by enough shared views (groups named, with the minimum); no world frame.
    """
    sensor_ids = list(intrinsics)
    object_points = np.asarray(object_points, dtype=float)
    check_observations(observations, intrinsics, len(object_points))
    ref = _reference(reference, sensor_ids)
    settings = _Settings(tolerance_s, min_shared_views, huber_px, reject_px, max_evaluations,
                         refine_intrinsics, lens, refine_level)  # fmt: skip
    fit = _fit(list(observations), intrinsics, object_points, ref, settings)
    floor_pose = FLOOR_BOARD_IN_WORLD if world_from_floor_board is None else world_from_floor_board
    world_from_ref, frame = _world_from_ref(
        fit, floor_stamp, tolerance_s, floor_pose, reference_world_from_camera
    )
    return _calibration(fit, sensor_ids, ref, world_from_ref, frame)


def _weigh(fit: _Fit, sensor_ids: Sequence[str], settings: _Settings) -> _Fit:
    """The fit, each sensor's refined intrinsics kept only where its views show them wrong.

    See :func:`~openptrack_py.calibration.evidence.weigh_intrinsics`.
    """
    if not settings.refine_intrinsics or settings.refine_level is None:
        return fit
    weighed = weigh_intrinsics(
        fit.problem, fit.x, settings.huber_px, settings.max_evaluations, settings.refine_level
    )
    return replace(
        fit,
        problem=weighed.problem,
        x=weighed.x,
        evidence=dict(zip(sensor_ids, weighed.evidence, strict=True)),
        iterations=weighed.iterations or fit.iterations,
        total_iterations=fit.total_iterations + weighed.total_iterations,
        final_cost=weighed.final_cost,
    )


def _as_seen(
    observations: Sequence[BoardObservation], intrinsics: Mapping[str, Intrinsics]
) -> list[BoardObservation]:
    """The views with their corners where each sensor's reported lens imaged them.

    A sensor that reports its lens (a factory's terms) has its corners undistorted by
    it as the board is detected; a solve that refines the lens must see them as the
    camera did, and start from that lens, so that what it finds is the camera's whole
    lens, not what the reported one left.
    """
    out = []
    for obs in observations:
        k = intrinsics[obs.sensor_id]
        out.append(replace(obs, corners=distort_corners(obs.corners, k)) if k.has_lens else obs)
    return out


def _reference(reference: str | None, sensor_ids: Sequence[str]) -> str:
    """The sensor held fixed: ``reference``, else the first; raise if it is not a sensor."""
    ref = reference if reference is not None else sensor_ids[0]
    if ref not in sensor_ids:
        raise CalibrationError(
            f"checkerboard calibration: reference {ref!r} is not one of the sensors "
            f"({', '.join(sensor_ids)})"
        )
    return ref


def _calibration(
    fit: _Fit,
    sensor_ids: Sequence[str],
    reference: str,
    world_from_ref: np.ndarray,
    frame: str,
) -> ExtrinsicCalibration:
    """The refined poses in the world frame, with the report."""
    problem = fit.problem
    cams, boards = problem.unpack(fit.x)
    solved = _refined(
        problem,
        sensor_ids,
        lambda: zip(problem.image_sizes, problem.intrinsics(fit.x), strict=True),
    )
    refined = {s: Intrinsics(w, h, *(float(v) for v in k)) for s, ((w, h), k) in solved.items()}
    return ExtrinsicCalibration(
        world_from_optical={s: world_from_ref @ invert(cams[i]) for i, s in enumerate(sensor_ids)},
        world_from_board={
            p.stamp: world_from_ref @ boards[i] for i, p in enumerate(fit.placements)
        },
        report=_report(fit, sensor_ids, reference, frame),
        intrinsics=refined,
    )


def _report(fit: _Fit, sensor_ids: Sequence[str], reference: str, frame: str) -> CalibrationReport:
    """The report of a refinement: residuals per sensor, counts, solver figures."""
    problem = fit.problem
    errors = np.where(problem.mask, problem.view_errors(fit.x), np.nan)
    index = {s: i for i, s in enumerate(sensor_ids)}
    return CalibrationReport(
        reference=reference,
        rms_px={
            s: float(np.sqrt(np.nanmean(errors[problem.view_sensor == index[s]] ** 2)))
            for s in sensor_ids
        },
        views={s: int(np.sum(problem.view_sensor == index[s])) for s in sensor_ids},
        pair_views=pair_views(fit.observations, fit.placements),
        placements=len(fit.placements),
        iterations=fit.iterations,
        rounds=fit.rounds,
        total_iterations=fit.total_iterations,
        initial_cost=fit.initial_cost,
        final_cost=fit.final_cost,
        world_frame=frame,
        rejected_views=fit.rejected_views,
        rejected_corners=int((~problem.mask).sum()),
        intrinsics_refined=problem.refine_intrinsics,
        intrinsics_sd=_refined(
            problem,
            sensor_ids,
            lambda: (tuple(float(v) for v in sd) for sd in problem.intrinsics_sd(fit.x)),
        ),
        intrinsics_evidence=dict(fit.evidence),
        distortion_px=_refined(problem, sensor_ids, lambda: problem.distortion_px(fit.x).tolist()),
    )


def _refined(
    problem: BundleProblem, sensor_ids: Sequence[str], values: Callable[[], Iterable[T]]
) -> dict[str, T]:
    """``values()`` (one per sensor) of the sensors whose intrinsics were refined.

    Empty when none were; a sensor that kept its given intrinsics has none to report.
    """
    if not problem.refine_intrinsics:
        return {}
    pairs = zip(sensor_ids, values(), problem.fixed, strict=True)
    return {s: v for s, v, kept in pairs if not kept}


# --------------------------------------------------------------------------- refinement


@dataclass(frozen=True)
class _Settings:
    """The refinement's settings (see :func:`calibrate_extrinsics`)."""

    tolerance_s: float
    min_shared_views: int
    huber_px: float
    reject_px: float
    max_evaluations: int
    refine_intrinsics: bool = False
    lens: str = "radial"
    refine_level: float | None = REFINE_LEVEL
    max_rounds: int = 25

    def __post_init__(self) -> None:
        if self.lens not in LENS_MODELS:
            raise CalibrationError(
                f"checkerboard calibration: lens {self.lens!r} is not one of "
                f"{', '.join(LENS_MODELS)}"
            )


@dataclass(frozen=True, eq=False)
class _Fit:
    """The refinement's outcome (see :func:`_fit`)."""

    problem: BundleProblem
    x: np.ndarray
    observations: list[BoardObservation]
    placements: list[Placement]
    iterations: int
    initial_cost: float
    final_cost: float
    rejected_views: tuple[tuple[str, float], ...]
    rounds: int
    total_iterations: int
    evidence: dict[str, IntrinsicsEvidence] = field(default_factory=dict)


def _fit(
    observations: list[BoardObservation],
    intrinsics: Mapping[str, Intrinsics],
    object_points: np.ndarray,
    reference: str,
    settings: _Settings,
) -> _Fit:
    """Chain, refine, reject outlying views and corners, refine again until none are left."""
    sensor_ids = list(intrinsics)
    if settings.refine_intrinsics:
        observations = _as_seen(observations, intrinsics)
    masks = [np.ones(len(object_points), dtype=bool) for _ in observations]
    rejected: list[tuple[str, float]] = []
    cam_from_ref: dict[str, np.ndarray] | None = None  # after a rejection, the last solve's
    k_start: np.ndarray | None = None  # ... and its intrinsics
    rounds = total = 0
    for _ in range(settings.max_rounds):
        placements = group_placements(observations, settings.tolerance_s)
        counts = pair_views(observations, placements)
        check_connected(sensor_ids, counts, settings.min_shared_views)
        if cam_from_ref is None:
            cam_from_ref = chain_sensors(
                observations, placements, sensor_ids, reference, settings.min_shared_views
            )
        problem, flat = _problem(
            observations, placements, masks, intrinsics, object_points, reference,
            settings.refine_intrinsics, settings.lens,
        )  # fmt: skip
        x0 = problem.pack(
            np.stack([cam_from_ref[s] for s in sensor_ids]),
            board_guesses(observations, placements, cam_from_ref),
            k_start,
        )
        x, iterations, cost0, cost = solve(
            problem, x0, settings.huber_px, settings.max_evaluations
        )
        rounds, total = rounds + 1, total + iterations
        drop, corners = _outliers(problem, x, flat, settings.reject_px)
        if not drop and not corners:
            break
        for i, c in corners:
            masks[i][c] = False
        rejected += [(observations[i].sensor_id, observations[i].stamp) for i in sorted(drop)]
        observations = [o for i, o in enumerate(observations) if i not in drop]
        masks = [m for i, m in enumerate(masks) if i not in drop]
        cam_from_ref = dict(zip(sensor_ids, problem.unpack(x)[0], strict=True))
        k_start = problem.intrinsics(x) if settings.refine_intrinsics else None
        _check_left(observations, sensor_ids, settings.reject_px)
    fit = _Fit(
        problem, x, observations, placements, iterations, cost0, cost, tuple(rejected),
        rounds, total,
    )  # fmt: skip
    return _weigh(fit, sensor_ids, settings)


def _problem(
    observations: Sequence[BoardObservation],
    placements: Sequence[Placement],
    masks: Sequence[np.ndarray],
    intrinsics: Mapping[str, Intrinsics],
    object_points: np.ndarray,
    reference: str,
    refine_intrinsics: bool = False,
    lens: str = "radial",
) -> tuple[BundleProblem, list[int]]:
    """One round's bundle problem, and the index in ``observations`` of each of its views."""
    sensor_ids = list(intrinsics)
    index = {s: i for i, s in enumerate(sensor_ids)}
    flat = [i for placement in placements for i in placement.views]
    views = [
        (index[observations[i].sensor_id], p, observations[i].corners)
        for p, placement in enumerate(placements)
        for i in placement.views
    ]
    problem = BundleProblem(
        object_points, [intrinsics[s] for s in sensor_ids], index[reference], views,
        len(placements), [masks[i] for i in flat], refine_intrinsics, lens,
    )  # fmt: skip
    return problem, flat


def _outliers(
    problem: BundleProblem, x: np.ndarray, flat: Sequence[int], reject_px: float
) -> tuple[set[int], list[tuple[int, int]]]:
    """Observations to drop, else ``(observation, corner)`` pairs to mask.

    Indices are of ``observations`` (through ``flat``). Views go first: corners are only
    looked at once no view is an outlier.
    """
    drop = {flat[v] for v in view_outliers(problem, x, reject_px)}
    if drop:
        return drop, []
    return drop, [(flat[v], c) for v, c in corner_outliers(problem, x, reject_px)]
