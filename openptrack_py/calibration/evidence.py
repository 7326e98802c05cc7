"""Whether a checkerboard session shows a sensor's given intrinsics wrong.

Refining a camera's pinhole and lens with the poses always fits the corners a little
better, wrong given intrinsics or not: the refined model has 6 or 9 more unknowns per
sensor to fit the corners' noise with. Where the given model is right (a factory
calibration that holds), that fitting costs accuracy: on rendered sessions of units
reporting their exact lens, refining from 25 placements put 5 of 24 sensors more than
1 cm off where none were (``docs/calibration.md``). So a sensor's refinement is kept
only where the views show the given model wrong: a likelihood-ratio test (Wilks,
"The large-sample distribution of the likelihood ratio for testing composite
hypotheses", 1938) of the solve with every sensor refined against the same solve with
that sensor's intrinsics held as given. With Gaussian corner noise of variance
``sigma^2``, the rise of the corners' squared error ``dSSR / sigma^2`` is chi-square
with as many degrees of freedom as the sensor has refined terms when its given model
is right; the refinement is kept when the rise exceeds the quantile at ``level``
(``sigma^2`` from the refined solve's residuals). Corners whose errors are correlated
(a blurred frame, a bent board) inflate the rise, so such sessions refine more often
than ``level`` says: the test errs towards refining, what ``--refine-intrinsics``
always did before.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from openptrack_py.calibration.bundle import BundleProblem, solve

__all__ = ["REFINE_LEVEL", "IntrinsicsEvidence", "weigh_intrinsics"]

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


def _squared_error(problem: BundleProblem, x: np.ndarray) -> float:
    """Sum of the used corners' squared reprojection errors, pixels^2."""
    err = (problem.project(x) - problem.observed) * problem.mask[..., None]
    return float(np.sum(err**2))


def _held(problem: BundleProblem, x: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """``x`` with the intrinsics of the ``fixed`` sensors back at the given ones."""
    out = x.copy()
    block = out[problem.n_pose_params :].reshape(problem.sensors, problem.n_intrinsics)
    block[fixed] = 0.0
    return out


def weigh_intrinsics(
    problem: BundleProblem,
    x: np.ndarray,
    huber_px: float,
    max_evaluations: int,
    level: float = REFINE_LEVEL,
) -> tuple[BundleProblem, np.ndarray, list[IntrinsicsEvidence]]:
    """Keep each sensor's refined intrinsics only where its views show the given ones wrong.

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
    tuple of (BundleProblem, ndarray, list of IntrinsicsEvidence)
        The problem with the sensors whose intrinsics stay as given fixed, its solution
        (``x`` itself when every sensor's refinement is kept), and each sensor's evidence.
    """
    sensors = problem.sensors
    refined = _squared_error(problem, x)
    used = 2 * int(problem.mask.sum())
    variance = refined / max(used - problem.n_params, 1)
    threshold = float(chi2.ppf(1.0 - level, problem.n_intrinsics))
    evidence = []
    for s in range(sensors):
        fixed = np.arange(sensors) == s
        held = problem.with_fixed(fixed)
        x_held = solve(held, _held(problem, x, fixed), huber_px, max_evaluations)[0]
        rise = (_squared_error(held, x_held) - refined) / max(variance, 1e-12)
        evidence.append(IntrinsicsEvidence(float(rise), threshold))
    keep = np.array([not e.refined for e in evidence])
    if not keep.any():
        return problem, x, evidence
    final = problem.with_fixed(keep)
    x_final = solve(final, _held(problem, x, keep), huber_px, max_evaluations)[0]
    return final, x_final, evidence
