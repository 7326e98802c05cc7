"""Bundle adjustment of sensor and board poses by corner reprojection error.

Step 4 of the checkerboard calibration of Munaro et al., OpenPTrack (§4), refined as in
bundle adjustment (Triggs et al., "Bundle Adjustment — A Modern Synthesis"; as Kalibr
and multical do): :class:`BundleProblem` holds the unknowns (6 per non-reference sensor,
6 per placement and, when asked, 6 or 9 intrinsics per sensor: focal lengths, principal
point and two radial distortion terms, or OpenCV's five radial and tangential ones), the
residuals (projected minus observed corners, and
a weak prior on the intrinsics) and the Jacobian's sparsity; :func:`solve` runs
``scipy.optimize.least_squares`` with a Huber loss and Jacobian-scaled variables;
:func:`view_outliers` and :func:`corner_outliers` name the views and corners to reject
before solving again (as Kalibr rejects corners).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence

import numpy as np
from scipy import sparse
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from openptrack_py.detection.frame import Intrinsics
from openptrack_py.detection.lens import distort
from openptrack_py.geometry import invert

__all__ = [
    "INTRINSIC_NAMES",
    "INTRINSIC_PRIOR",
    "LENS_MODELS",
    "BundleProblem",
    "corner_outliers",
    "huber_cost",
    "huber_rho",
    "solve",
    "view_outliers",
]

INTRINSIC_NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
"""A camera's intrinsics in the order the problem holds them (the lens in OpenCV's)."""

LENS_MODELS = {"radial": 6, "full": 9}
"""Lens models the solve offers, with how many of :data:`INTRINSIC_NAMES` each solves:
``radial`` the pinhole and ``k1, k2``; ``full`` also the tangential ``p1, p2`` and
``k3``, OpenCV's five-term model (for a lens with visible decentering or strong
barrel distortion, from many placements reaching the image's corners)."""

INTRINSIC_PRIOR = (0.05, 0.05, 0.05, 0.05, 0.1, 0.1, 0.01, 0.01, 0.1)
"""Standard deviations of the weak prior on refined intrinsics, about the given ones:
``fx``, ``fy`` as a fraction of the given focal length, ``cx``, ``cy`` as a fraction of
the image's width and height, and the lens terms ``k1, k2, p1, p2, k3`` (absolute):
wide enough for a unit whose focal length and centre are a few percent off its type's,
for the few percent of distortion of a depth camera's lens and for a decentering of a
few thousandths (the tangential terms OpenCV fits to real lenses). The prior matters where the
views say little (a sensor with few views, all at one distance); the report's standard
deviations of the refined intrinsics say when they do
(:meth:`BundleProblem.intrinsics_sd`)."""

PRIOR_PX = 0.2
"""Pixels a one-standard-deviation departure from the prior costs, as one corner's
residual does: about the corner noise of a good detector."""


def _to_params(rot: np.ndarray, position: np.ndarray) -> np.ndarray:
    """Rotation vector of ``rot`` followed by ``position``."""
    return np.concatenate([Rotation.from_matrix(rot).as_rotvec(), position])


def _to_matrices(params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation matrices ``(n, 3, 3)`` and positions ``(n, 3)`` of ``(n, 6)`` params."""
    params = params.reshape(-1, 6)
    if not len(params):
        return np.zeros((0, 3, 3)), np.zeros((0, 3))
    return Rotation.from_rotvec(params[:, :3]).as_matrix(), params[:, 3:]


class BundleProblem:
    """Joint refinement of sensor and board poses by corner reprojection error.

    Unknowns, 6 per non-reference sensor then 6 per placement (then, with
    ``refine_intrinsics``, 6 or 9 per sensor): a sensor's orientation in the reference frame
    (rotation vector of ``ref_from_camera``) and its optical centre there; a board's
    orientation (of ``ref_from_board``) and its centre. Positions of centres rather than
    the translations of the transforms keep rotations and translations nearly
    independent (a camera turning about its own centre moves no other unknown), which
    keeps the problem well conditioned.
    Residuals: per view, per corner, the projected minus the observed pixel (u, v); with
    ``refine_intrinsics``, the prior's after them.

    Parameters
    ----------
    object_points : ndarray
        ``(n, 3)`` corners in the board frame.
    intrinsics : sequence of Intrinsics
        Per sensor index.
    reference : int
        Index of the fixed sensor.
    views : sequence of (int, int, ndarray)
        ``(sensor index, placement index, (n, 2) corners)`` per view.
    placements : int
        Number of placements.
    masks : sequence of ndarray, optional
        Per view, ``(n,)`` bool: the corners used (rejected corners' residuals are 0).
    refine_intrinsics : bool
        Also solve every sensor's ``fx, fy, cx, cy`` and lens distortion (of the given
        pixels, :mod:`openptrack_py.detection.lens`), 6 or 9 unknowns per sensor after
        the placements' (``lens``), started from the given intrinsics and their lens
        (a camera that reports its factory lens; none for most), under the weak prior
        :data:`INTRINSIC_PRIOR` about them (as many more residuals
        per sensor, after the corners'). They are solved as departures from the given
        ones in units of the prior's standard deviations: all start at 0 and are of
        order 1, where raw focal lengths and image centres (hundreds of pixels) beside
        lens terms of a few hundredths left the trust-region solver stopping early, far
        from the solution, on units whose lens moves corners by pixels.
    lens : {"radial", "full"}
        The lens terms solved with ``refine_intrinsics`` (:data:`LENS_MODELS`).
    fixed : sequence of bool, optional
        Per sensor: its intrinsics stay as given while the others' are refined (its
        unknowns remain, held at 0 by the prior and moving nothing).
    """

    def __init__(
        self,
        object_points: np.ndarray,
        intrinsics: Sequence[Intrinsics],
        reference: int,
        views: Sequence[tuple[int, int, np.ndarray]],
        placements: int,
        masks: Sequence[np.ndarray] | None = None,
        refine_intrinsics: bool = False,
        lens: str = "radial",
        fixed: Sequence[bool] | None = None,
    ) -> None:
        if lens not in LENS_MODELS:
            raise ValueError(f"lens: {lens!r} is not one of {', '.join(LENS_MODELS)}")
        self.object_points = np.asarray(object_points, dtype=float)
        self._board_centre = self.object_points.mean(axis=0)
        self._centred = self.object_points - self._board_centre
        self.sensors = len(intrinsics)
        self.reference = reference
        self.placements = placements
        self.view_sensor = np.array([v[0] for v in views], dtype=int)
        self.view_placement = np.array([v[1] for v in views], dtype=int)
        self.observed = np.stack([np.asarray(v[2], dtype=float) for v in views])
        n = len(self.object_points)
        self.mask = (
            np.ones((len(views), n), dtype=bool)
            if masks is None
            else np.stack([np.asarray(m, dtype=bool) for m in masks])
        )
        self.refine_intrinsics = refine_intrinsics
        self.n_intrinsics = LENS_MODELS[lens] if refine_intrinsics else 0
        self.image_sizes = [(i.width, i.height) for i in intrinsics]
        given = [[i.fx, i.fy, i.cx, i.cy, *i.distortion] for i in intrinsics]
        self.given = np.array(given, dtype=float).reshape(-1, 9)  # INTRINSIC_NAMES per sensor
        size = np.array([[i.fx, i.fy, i.width, i.height] + [1.0] * 5 for i in intrinsics])
        self._prior_full = (size * np.array(INTRINSIC_PRIOR))[:, : self.n_intrinsics]
        self.fixed = np.zeros(self.sensors, dtype=bool)
        self._prior_sigma = self._prior_full
        if fixed is not None:
            self._fix(fixed)
        # Parameter block of each sensor (-1 for the reference).
        order = [s for s in range(self.sensors) if s != reference]
        self.sensor_block = np.full(self.sensors, -1, dtype=int)
        self.sensor_block[order] = np.arange(len(order))

    def _fix(self, fixed: Sequence[bool]) -> None:
        self.fixed = np.asarray(fixed, dtype=bool).copy()
        self._prior_sigma = np.where(self.fixed[:, None], 0.0, self._prior_full)

    def with_fixed(self, fixed: Sequence[bool]) -> BundleProblem:
        """The same problem with the intrinsics of the ``fixed`` sensors held as given."""
        out = copy.copy(self)
        out._fix(fixed)
        return out

    @property
    def n_sensor_params(self) -> int:
        """Parameters of the non-reference sensors."""
        return 6 * (self.sensors - 1)

    @property
    def n_pose_params(self) -> int:
        """Unknowns of the poses: the non-reference sensors', then the placements'."""
        return self.n_sensor_params + 6 * self.placements

    @property
    def n_params(self) -> int:
        """Number of unknowns (the poses', then the intrinsics' if refined)."""
        return self.n_pose_params + self.n_intrinsics * self.sensors

    def intrinsics(self, x: np.ndarray) -> np.ndarray:
        """``(sensors, 9)``: each sensor's :data:`INTRINSIC_NAMES` at ``x``."""
        if not self.refine_intrinsics:
            return self.given
        out = self.given.copy()
        out[:, : self.n_intrinsics] += self._intrinsic_block(x) * self._prior_sigma
        return out

    def _intrinsic_block(self, x: np.ndarray) -> np.ndarray:
        """``(sensors, solved)``: the intrinsics' unknowns, in their prior's deviations."""
        return x[self.n_pose_params :].reshape(self.sensors, self.n_intrinsics)

    def pack(
        self,
        camera_from_ref: np.ndarray,
        ref_from_board: np.ndarray,
        intrinsics: np.ndarray | None = None,
    ) -> np.ndarray:
        """Parameter vector of ``(sensors, 4, 4)`` and ``(placements, 4, 4)`` poses.

        With refined intrinsics, ``intrinsics`` ``(sensors, 9)`` starts them (the given
        ones if omitted).
        """
        blocks = []
        for s in range(self.sensors):
            if s != self.reference:
                pose = invert(camera_from_ref[s])
                blocks.append(_to_params(pose[:3, :3], pose[:3, 3]))
        for pose in ref_from_board:
            centre = pose[:3, :3] @ self._board_centre + pose[:3, 3]
            blocks.append(_to_params(pose[:3, :3], centre))
        if self.refine_intrinsics:
            if intrinsics is not None:
                solved = slice(0, self.n_intrinsics)
                moved = (intrinsics - self.given)[:, solved]
                start = np.divide(
                    moved, self._prior_sigma, out=np.zeros_like(moved), where=self._prior_sigma > 0
                )
                blocks.append(start.ravel())
            else:
                blocks.append(np.zeros(self.n_intrinsics * self.sensors))
        return np.concatenate([np.zeros(0), *blocks])

    def _rotations(self, x: np.ndarray) -> tuple[np.ndarray, ...]:
        """``ref_from_camera`` rotations and centres per sensor, then the boards'."""
        cam_rot = np.tile(np.eye(3), (self.sensors, 1, 1))
        cam_pos = np.zeros((self.sensors, 3))
        rot, pos = _to_matrices(x[: self.n_sensor_params])
        others = self.sensor_block >= 0
        cam_rot[others] = rot[self.sensor_block[others]]
        cam_pos[others] = pos[self.sensor_block[others]]
        board_rot, board_pos = _to_matrices(x[self.n_sensor_params : self.n_pose_params])
        return cam_rot, cam_pos, board_rot, board_pos

    def unpack(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``camera_from_ref`` per sensor and ``ref_from_board`` per placement, 4x4 each."""
        cam_rot, cam_pos, board_rot, board_pos = self._rotations(x)
        cams = np.tile(np.eye(4), (self.sensors, 1, 1))
        cams[:, :3, :3] = cam_rot.transpose(0, 2, 1)
        cams[:, :3, 3] = -np.einsum("sji,sj->si", cam_rot, cam_pos)
        boards = np.tile(np.eye(4), (self.placements, 1, 1))
        boards[:, :3, :3] = board_rot
        boards[:, :3, 3] = board_pos - board_rot @ self._board_centre
        return cams, boards

    def project(self, x: np.ndarray) -> np.ndarray:
        """``(views, n, 2)`` projected corners."""
        cam_rot, cam_pos, board_rot, board_pos = self._rotations(x)
        ref_pts = np.einsum("pij,nj->pni", board_rot, self._centred) + board_pos[:, None]
        s = self.view_sensor
        rel = ref_pts[self.view_placement] - cam_pos[s, None]
        cam_pts = np.einsum("vji,vnj->vni", cam_rot[s], rel)  # R^T (X - c)
        k = self.intrinsics(x)[s]
        z = cam_pts[..., 2]
        if not self.refine_intrinsics:  # the pinhole alone, as before intrinsics were solved
            u = k[:, None, 0] * cam_pts[..., 0] / z + k[:, None, 2]
            v = k[:, None, 1] * cam_pts[..., 1] / z + k[:, None, 3]
            return np.stack([u, v], axis=-1)
        xn, yn = distort(cam_pts[..., 0] / z, cam_pts[..., 1] / z, k[:, None, 4:])
        u = k[:, None, 0] * xn + k[:, None, 2]
        v = k[:, None, 1] * yn + k[:, None, 3]
        return np.stack([u, v], axis=-1)

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Projected minus observed pixels, flattened view by view, corner by corner.

        Rejected corners (see ``masks``) give zeros. With refined intrinsics, the prior's
        residuals follow, one per solved intrinsic.
        """
        corners = ((self.project(x) - self.observed) * self.mask[..., None]).ravel()
        if not self.refine_intrinsics:
            return corners
        return np.concatenate([corners, PRIOR_PX * self._intrinsic_block(x).ravel()])

    def intrinsics_sd(self, x: np.ndarray) -> np.ndarray:
        """``(sensors, solved)``: standard deviations of the refined intrinsics at ``x``.

        From the Gauss-Newton covariance ``(J'J)^-1`` of the whitened residuals (``J`` by
        forward differences): the corners' rows divided by their measured scatter per
        coordinate, the prior's by :data:`PRIOR_PX` (so that the prior counts with its
        own standard deviations), so an intrinsic the views barely determine shows a
        large one, at most its prior's. Zeros when the intrinsics are not refined.
        """
        if not self.refine_intrinsics:
            return np.zeros((self.sensors, 0))
        base = self.residuals(x)
        jac = np.empty((len(base), self.n_params))
        for j in range(self.n_params):
            step = 1e-6 * max(1.0, abs(float(x[j])))
            moved = x.copy()
            moved[j] += step
            jac[:, j] = (self.residuals(moved) - base) / step
        used = 2 * int(self.mask.sum())
        n = self.observed.size
        corners = base[:n]
        scatter = float(corners @ corners) / max(used - self.n_params, 1)
        jac[:n] /= max(math.sqrt(scatter), 1e-12)
        jac[n:] /= PRIOR_PX
        cov = np.linalg.pinv(jac.T @ jac)
        sd = np.sqrt(np.maximum(np.diag(cov)[self.n_pose_params :], 0.0))
        return sd.reshape(self.sensors, self.n_intrinsics) * self._prior_sigma

    def distortion_px(self, x: np.ndarray) -> np.ndarray:
        """``(sensors,)``: how far the distortion moves a corner seen, at most.

        Pixels, the largest over each sensor's used corners (beyond them the fitted
        terms say nothing); zeros when not refined.
        """
        out = np.zeros(self.sensors)
        if not self.refine_intrinsics:
            return out
        k = self.intrinsics(x)
        for s in range(self.sensors):
            mine = self.view_sensor == s
            if not mine.any():
                continue
            pix = self.observed[mine][self.mask[mine]]
            xn = (pix[:, 0] - k[s, 2]) / k[s, 0]
            yn = (pix[:, 1] - k[s, 3]) / k[s, 1]
            xd, yd = distort(xn, yn, k[s, 4:])
            out[s] = float(np.hypot((xd - xn) * k[s, 0], (yd - yn) * k[s, 1]).max())
        return out

    def view_errors(self, x: np.ndarray) -> np.ndarray:
        """``(views, n)`` reprojection error of every corner (rejected ones too), pixels."""
        return np.linalg.norm(self.project(x) - self.observed, axis=-1)

    def view_rms(self, x: np.ndarray) -> np.ndarray:
        """Per view, the RMS reprojection error of its used corners, pixels."""
        errors = self.view_errors(x)
        return np.sqrt((errors**2 * self.mask).sum(axis=1) / np.maximum(self.mask.sum(axis=1), 1))

    def sparsity(self) -> sparse.csr_matrix:
        """Which residuals depend on which parameters (``least_squares``' ``jac_sparsity``).

        A view's residuals depend on its sensor's 6 pose parameters (none for the
        reference), its placement's 6 and, when refined, its sensor's intrinsics; each
        prior residual on one intrinsic alone.
        """
        n_res = 2 * self.object_points.shape[0]
        rows, cols = [], []
        for view, (s, p) in enumerate(zip(self.view_sensor, self.view_placement, strict=True)):
            r = np.arange(view * n_res, (view + 1) * n_res)
            blocks = [self.n_sensor_params + 6 * p + np.arange(6)]
            if self.sensor_block[s] >= 0:
                blocks.append(6 * self.sensor_block[s] + np.arange(6))
            if self.refine_intrinsics:
                m = self.n_intrinsics
                blocks.append(self.n_pose_params + m * s + np.arange(m))
            c = np.concatenate(blocks)
            rows.append(np.repeat(r, len(c)))
            cols.append(np.tile(c, len(r)))
        n_rows = n_res * len(self.view_sensor)
        if self.refine_intrinsics:
            k = np.arange(self.n_intrinsics * self.sensors)
            rows.append(n_rows + k)
            cols.append(self.n_pose_params + k)
            n_rows += len(k)
        rows_a, cols_a = np.concatenate(rows), np.concatenate(cols)
        shape = (n_rows, self.n_params)
        return sparse.csr_matrix((np.ones(len(rows_a), dtype=np.int8), (rows_a, cols_a)), shape)


def solve(
    problem: BundleProblem, x0: np.ndarray, huber_px: float, max_evaluations: int
) -> tuple[np.ndarray, int, float, float]:
    """Refined parameters, iterations, initial and final cost.

    The sparse trust-region steps are solved by LSMR to a tight tolerance: at its default
    (1e-6) the Gauss-Newton steps of this poorly scaled problem (metres against radians
    against pixels) are too rough and the solver crawls for hundreds of iterations.

    The Huber loss is annealed: when the start is far from the answer (the median corner
    several times ``huber_px`` off, as with a lens whose distortion the start does not
    know), a first solve uses a threshold of three median corner errors, and the second
    the given one from there (graduated robustness, as bundle adjusters anneal their
    robust kernels). With almost every residual in the loss's linear part from the
    start, the trust-region solver crawls: on a rendered session of units with lenses
    moving corners by up to 11 px it had cut the cost by a third after 200 evaluations,
    where the annealed solve converges in a few dozen. The first solve has half of
    ``max_evaluations``, the second what is left (at least one), and the first's answer
    is kept only if it lowers the cost at ``huber_px``.

    Parameters
    ----------
    problem : BundleProblem
        The problem.
    x0 : ndarray
        Initial parameters (:meth:`BundleProblem.pack`).
    huber_px : float
        Residual beyond which the loss grows linearly, pixels.
    max_evaluations : int
        Cap on residual evaluations.

    Returns
    -------
    tuple of (ndarray, int, float, float)
        Refined parameters, Jacobian evaluations, and the ``least_squares`` cost before
        and after.
    """
    initial = huber_cost(problem.residuals(x0), huber_px)
    start = 3.0 * float(np.median(problem.view_errors(x0)[problem.mask]))
    x, iterations, budget = x0, 0, max_evaluations
    pattern = problem.sparsity()
    for scale in ([start] if start > huber_px else []) + [huber_px]:
        first = scale != huber_px
        result = least_squares(
            problem.residuals,
            x,
            jac_sparsity=pattern,
            method="trf",
            tr_solver="lsmr",
            tr_options={"atol": 1e-14, "btol": 1e-14, "maxiter": max(1000, 4 * problem.n_params)},
            loss="huber",
            f_scale=scale,
            x_scale="jac",
            xtol=1e-10,
            ftol=1e-10,
            gtol=1e-10,
            max_nfev=max(budget // 2, 1) if first else max(budget, 1),
        )
        budget -= result.nfev
        iterations += int(result.njev or result.nfev)
        if not first or huber_cost(problem.residuals(result.x), huber_px) <= initial:
            x = result.x
    return x, iterations, initial, float(result.cost)


def huber_rho(residuals: np.ndarray, scale: float) -> np.ndarray:
    """Each residual's Huber loss in pixels^2: its square within ``scale``, linear beyond."""
    z = (np.asarray(residuals, dtype=float) / scale) ** 2
    return scale**2 * np.where(z <= 1.0, z, 2.0 * np.sqrt(z) - 1.0)


def huber_cost(residuals: np.ndarray, scale: float) -> float:
    """``least_squares``' cost of residuals under its ``huber`` loss with ``f_scale=scale``."""
    return float(0.5 * huber_rho(residuals, scale).sum())


def view_outliers(problem: BundleProblem, x: np.ndarray, reject_px: float) -> list[int]:
    """Views to reject: per placement, the worst view if its RMS is far above the rest.

    Far above: beyond both ``reject_px`` and four times the median view's RMS. Only the
    worst view of a placement goes at a time: a wrong view drags the board's pose and
    with it the placement's good views, which fit again once it is gone.

    Returns
    -------
    list of int
        Indices of the views of ``problem`` to reject.
    """
    rms = problem.view_rms(x)
    limit = max(reject_px, 4.0 * float(np.median(rms)))
    out = []
    for p in np.unique(problem.view_placement[rms > limit]):
        members = np.flatnonzero(problem.view_placement == p)
        out.append(int(members[np.argmax(rms[members])]))
    return out


def corner_outliers(
    problem: BundleProblem, x: np.ndarray, reject_px: float
) -> list[tuple[int, int]]:
    """Corners to reject: per view, the worst corner if its error is far above the rest.

    Far above: beyond both half of ``reject_px`` and four times the median corner error
    of the view's sensor (a corner error is Rayleigh-distributed: four medians are 4.7
    standard deviations per axis, which a well-found corner passes once in 60 thousand).
    Each sensor against its own median: a camera whose corners are noisier than the
    others' (lower resolution, a blurred or far board) is honest, and measured against
    the sharper cameras it would lose a corner in every other view, round after round.
    One corner per view at a time, as for views.

    Returns
    -------
    list of (int, int)
        ``(view, corner)`` indices to reject.
    """
    errors = np.where(problem.mask, problem.view_errors(x), 0.0)
    median = np.zeros(int(problem.view_sensor.max(initial=-1)) + 1)
    for s in np.unique(problem.view_sensor):
        mine = problem.view_sensor == s
        median[s] = np.median(errors[mine][problem.mask[mine]])
    limit = np.maximum(0.5 * reject_px, 4.0 * median[problem.view_sensor])
    worst = np.argmax(errors, axis=1)
    return [(int(v), int(worst[v])) for v in np.flatnonzero(errors.max(axis=1) > limit)]
