"""An Unscented Kalman Filter vectorised over every track at once.

Same algorithm and sigma-point scheme as filterpy's ``UnscentedKalmanFilter`` with
``MerweScaledSigmaPoints`` (filterpy >= 2: sigma points are redrawn from the predicted
state before the update), but the state of ``N`` tracks is one ``(N, n)`` array and one
``(N, n, n)`` covariance stack, so a step costs a handful of numpy calls instead of
``N`` Python objects. The test suite checks it against filterpy and, with linear models,
against a linear Kalman filter.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

StateFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""``fx(sigmas (N, k, n), dt (N,)) -> (N, k, n)``: propagate sigma points."""
MeasureFn = Callable[[np.ndarray], np.ndarray]
"""``hx(sigmas (N, k, n)) -> (N, k, m)``: predicted measurements of sigma points."""


@dataclass(frozen=True)
class MerweSigmaPoints:
    """Van der Merwe's scaled sigma points (``2n + 1`` per state).

    Parameters
    ----------
    n : int
        State dimension.
    alpha, beta, kappa : float
        Spread and weighting parameters.
    """

    n: int
    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0
    wm: np.ndarray = field(init=False, repr=False)
    wc: np.ndarray = field(init=False, repr=False)
    scale: float = field(init=False, repr=False)

    def __post_init__(self) -> None:
        lam = self.alpha**2 * (self.n + self.kappa) - self.n
        c = 0.5 / (self.n + lam)
        wm = np.full(2 * self.n + 1, c)
        wc = wm.copy()
        wm[0] = lam / (self.n + lam)
        wc[0] = wm[0] + 1.0 - self.alpha**2 + self.beta
        object.__setattr__(self, "wm", wm)
        object.__setattr__(self, "wc", wc)
        object.__setattr__(self, "scale", self.n + lam)

    def points(self, x: np.ndarray, cov: np.ndarray) -> np.ndarray:
        """Sigma points ``(N, 2n + 1, n)`` of states ``x (N, n)`` and covariances ``(N, n, n)``."""
        root = _cholesky(self.scale * cov)  # lower triangular: columns are the offsets
        offsets = np.swapaxes(root, 1, 2)  # (N, n, n): row i is column i of the root
        return np.concatenate(
            [x[:, None, :], x[:, None, :] + offsets, x[:, None, :] - offsets], axis=1
        )


def _cholesky(mat: np.ndarray) -> np.ndarray:
    """Batched Cholesky factor, repairing matrices that lost positive definiteness."""
    mat = 0.5 * (mat + np.swapaxes(mat, -1, -2))
    try:
        return np.linalg.cholesky(mat)
    except np.linalg.LinAlgError:
        # Clip negative eigenvalues (round-off after many updates) and retry.
        vals, vecs = np.linalg.eigh(mat)
        vals = np.maximum(vals, 1e-12)
        fixed = (vecs * vals[..., None, :]) @ np.swapaxes(vecs, -1, -2)
        return np.linalg.cholesky(0.5 * (fixed + np.swapaxes(fixed, -1, -2)))


def _weighted_mean(points: np.ndarray, wm: np.ndarray) -> np.ndarray:
    return np.einsum("k,nkd->nd", wm, points)


def _weighted_cov(da: np.ndarray, db: np.ndarray, wc: np.ndarray) -> np.ndarray:
    return np.einsum("k,nki,nkj->nij", wc, da, db)


@dataclass(frozen=True)
class Projection:
    """Predicted measurement of every track, before any detection is known.

    Parameters
    ----------
    z : ndarray
        ``(N, m)`` predicted measurements.
    pzz : ndarray
        ``(N, m, m)`` their covariance, *without* measurement noise.
    pxz : ndarray
        ``(N, n, m)`` state-measurement cross covariance.
    """

    z: np.ndarray
    pzz: np.ndarray
    pxz: np.ndarray


class UnscentedKalmanFilter:
    """Predict, project and update a stack of Gaussian states with the unscented transform.

    Parameters
    ----------
    points : MerweSigmaPoints
        Sigma-point scheme (its ``n`` is the state dimension).
    """

    def __init__(self, points: MerweSigmaPoints) -> None:
        self.points = points

    def predict(
        self,
        x: np.ndarray,
        cov: np.ndarray,
        dt: np.ndarray,
        fx: StateFn,
        q: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Propagate states by ``dt`` (one per track) through ``fx``, adding noise ``q``.

        Parameters
        ----------
        x, cov : ndarray
            ``(N, n)`` states and ``(N, n, n)`` covariances.
        dt : ndarray
            ``(N,)`` time steps, seconds.
        fx : callable
            State transition of sigma points.
        q : ndarray
            ``(N, n, n)`` process noise for each step.
        """
        if len(x) == 0:
            return x.copy(), cov.copy()
        sigmas = fx(self.points.points(x, cov), dt)
        x_pred = _weighted_mean(sigmas, self.points.wm)
        d = sigmas - x_pred[:, None, :]
        return x_pred, _weighted_cov(d, d, self.points.wc) + q

    def project(self, x: np.ndarray, cov: np.ndarray, hx: MeasureFn) -> Projection:
        """Predicted measurement and covariances (sigma points redrawn from ``x, cov``)."""
        sigmas = self.points.points(x, cov)
        zs = hx(sigmas)
        z = _weighted_mean(zs, self.points.wm)
        dz = zs - z[:, None, :]
        dx = sigmas - x[:, None, :]
        wc = self.points.wc
        return Projection(z=z, pzz=_weighted_cov(dz, dz, wc), pxz=_weighted_cov(dx, dz, wc))

    @staticmethod
    def update(
        x: np.ndarray,
        cov: np.ndarray,
        proj: Projection,
        z: np.ndarray,
        r: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Correct states with measurements ``z (N, m)`` of noise ``r (N, m, m)``."""
        s = proj.pzz + r
        s_inv = np.linalg.inv(s)
        gain = proj.pxz @ s_inv
        x_new = x + np.einsum("nij,nj->ni", gain, z - proj.z)
        cov_new = cov - gain @ s @ np.swapaxes(gain, 1, 2)
        return x_new, 0.5 * (cov_new + np.swapaxes(cov_new, 1, 2))
