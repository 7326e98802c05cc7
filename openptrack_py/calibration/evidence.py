"""Whether a checkerboard session shows a sensor's given intrinsics wrong.

Refining a camera's pinhole and lens with the poses always fits the corners a little
better, wrong given intrinsics or not: the refined model has 6 or 9 more unknowns per
sensor to fit the corners' noise with. Where the given model is right (a factory
calibration that holds), that fitting costs accuracy: on rendered sessions of units
reporting their exact lens, refining from 25 placements put 6 of 48 sensors more than
1 cm off where none were (``docs/calibration.md``). So a sensor's refinement is kept
only where the views show the given model wrong: a likelihood-ratio test (Wilks,
"The large-sample distribution of the likelihood ratio for testing composite
hypotheses", 1938) of the solve with every sensor refined against the same solve with
that sensor's intrinsics held as given. With Gaussian corner noise of variance
``sigma^2``, the rise of the corners' squared error ``dSSR / sigma^2`` is chi-square
with as many degrees of freedom as the sensor has refined terms when its given model
is right; the refinement is kept when the rise exceeds the quantile at ``level``.
Sensors differ in noise (a low-resolution or blurred camera beside sharp ones), and the
solves weigh every corner alike, so the rise counted is the held sensor's own, divided
by its own ``sigma^2`` (from the refined solve), of the errors the solves minimise
(squared within the Huber threshold, growing linearly beyond). The other sensors'
rises are left out: counted, a noisy sensor pulling the boards they share passes its
own noise off as evidence. Leaving them out makes the test a little conservative (a
sensor's wrong intrinsics partly absorbed by the others' poses are not counted).
Corners whose errors are correlated (a blurred frame, a bent board) inflate
the rise, so such sessions refine more often than ``level`` says: the test errs towards
refining, what ``--refine-intrinsics`` always did before.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from openptrack_py.calibration.bundle import BundleProblem, huber_cost, huber_rho, solve

__all__ = ["REFINE_LEVEL", "IntrinsicsEvidence", "WeighedFit", "weigh_intrinsics"]

REFINE_LEVEL = 0.001
"""Chance that a sensor whose given intrinsics are right gets them refined anyway."""


@dataclass(frozen=True)
class IntrinsicsEvidence:
    """What one sensor's views say of its given intrinsics.

    Parameters
    ----------
    statistic : float
        Rise of the corners' squared error when the sensor's intrinsics are held as
        given, in units of the corner noise's variance.
    threshold : float
        The chi-square quantile the rise must exceed for the refinement to be kept.
    """

    statistic: float
    threshold: float

    @property
    def refined(self) -> bool:
        """Whether the views show the given intrinsics wrong (the refinement is kept)."""
        return self.statistic > self.threshold


def _per_sensor(problem: BundleProblem, x: np.ndarray, huber_px: float) -> np.ndarray:
    """``(sensors,)``: each sensor's share of what the solve minimises, pixels^2.

    Twice the Huber cost of its used corners' errors (the squared error where they are
    within ``huber_px``, growing linearly beyond), so that what is differenced is what
    the solves minimise.
    """
    err = ((problem.project(x) - problem.observed) * problem.mask[..., None]).reshape(
        len(problem.observed), -1
    )
    per_view = huber_rho(err, huber_px).sum(axis=1)
    return np.bincount(problem.view_sensor, per_view, minlength=problem.sensors)


def _held(problem: BundleProblem, x: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """``x`` with the intrinsics of the ``fixed`` sensors back at the given ones."""
    out = x.copy()
    block = out[problem.n_pose_params :].reshape(problem.sensors, problem.n_intrinsics)
    block[fixed] = 0.0
    return out


@dataclass(frozen=True, eq=False)
class WeighedFit:
    """The outcome of :func:`weigh_intrinsics`.

    Parameters
    ----------
    problem : BundleProblem
        The problem, the sensors that keep their given intrinsics fixed.
    x : ndarray
        Its solution.
    evidence : list of IntrinsicsEvidence
        Each sensor's.
    iterations, total_iterations : int
        Jacobian evaluations of the last solve, and of all the test's solves.
    final_cost : float
        ``least_squares``' cost at ``x``.
    """

    problem: BundleProblem
    x: np.ndarray
    evidence: list[IntrinsicsEvidence]
    iterations: int
    total_iterations: int
    final_cost: float


def weigh_intrinsics(
    problem: BundleProblem,
    x: np.ndarray,
    huber_px: float,
    max_evaluations: int,
    level: float = REFINE_LEVEL,
) -> WeighedFit:
    """Keep each sensor's refined intrinsics only where its views show the given ones wrong.

    Each sensor's rise is of its own corners, divided by their own noise variance (from
    the refined solve, the degrees of freedom shared out by corners used; see the
    module).

    Parameters
    ----------
    problem : BundleProblem
        The solved problem, every sensor's intrinsics refined.
    x : ndarray
        Its solution.
    huber_px, max_evaluations : float, int
        As for :func:`~openptrack_py.calibration.bundle.solve`.
    level : float
        Chance of refining a sensor whose given intrinsics are right.

    Returns
    -------
    WeighedFit
        The problem with the sensors whose intrinsics stay as given fixed and its
        solution (``problem`` and ``x`` themselves when every refinement is kept), the
        evidence, and the solves' figures.
    """
    sensors = problem.sensors
    refined = _per_sensor(problem, x, huber_px)
    used = 2 * problem.mask.sum(axis=1)
    corners = np.bincount(problem.view_sensor, used, minlength=sensors)
    # degrees of freedom of each sensor's residuals: its corners, less its share of unknowns
    dof = corners * (1.0 - problem.n_params / max(float(corners.sum()), 1.0))
    variance = np.maximum(refined / np.maximum(dof, 1.0), 1e-12)
    threshold = float(chi2.ppf(1.0 - level, problem.n_intrinsics))
    evidence, total = [], 0
    for s in range(sensors):
        fixed = np.arange(sensors) == s
        held = problem.with_fixed(fixed)
        x_held, iterations, _, _ = solve(held, _held(problem, x, fixed), huber_px, max_evaluations)
        total += iterations
        rise = (_per_sensor(held, x_held, huber_px)[s] - refined[s]) / variance[s]
        evidence.append(IntrinsicsEvidence(float(rise), threshold))
    keep = np.array([not e.refined for e in evidence])
    if not keep.any():
        cost = huber_cost(problem.residuals(x), huber_px)
        return WeighedFit(problem, x, evidence, 0, total, cost)
    final = problem.with_fixed(keep)
    x_final, iterations, _, cost = solve(final, _held(problem, x, keep), huber_px, max_evaluations)
    return WeighedFit(final, x_final, evidence, iterations, total + iterations, cost)
