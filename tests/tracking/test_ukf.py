"""The vectorised UKF against a linear Kalman filter and filterpy; covariances stay SPD."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import MerweScaledSigmaPoints
from filterpy.kalman import UnscentedKalmanFilter as FilterpyUKF
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from openptrack_py.tracking import (
    ConstantVelocity,
    MerweSigmaPoints,
    PositionMeasurement,
    UnscentedKalmanFilter,
)
from tests.tracking.helpers import (
    is_spd,
    linear_kf,
)

# ------------------------------------------------------------ UKF oracle tests


def test_ukf_with_linear_models_equals_linear_kalman_filter() -> None:
    rng = np.random.default_rng(7)
    n, steps = 6, 300
    motion = ConstantVelocity(0.7)
    meas = PositionMeasurement(0.08, 0.002)
    ukf = UnscentedKalmanFilter(MerweSigmaPoints(4))
    x = np.column_stack([rng.uniform(0, 8, (n, 2)), rng.normal(0, 1, (n, 2))])
    cov = np.stack([np.diag([0.05, 0.05, 2.0, 2.0])] * n)
    ref_x, ref_p = x.copy(), cov.copy()
    truth = x.copy()
    for _ in range(steps):
        # irregular steps, different for every track, sometimes long (coasting)
        dt = np.where(rng.random(n) < 0.05, rng.uniform(0.5, 3.0, n), rng.uniform(0.002, 0.1, n))
        truth[:, 0:2] += dt[:, None] * truth[:, 2:4]
        x, cov = ukf.predict(x, cov, dt, motion.fx, motion.noise(dt))
        seen = np.flatnonzero(rng.random(n) < 0.8)  # some tracks miss this step
        dist = rng.uniform(0.5, 8.0, n)
        r = meas.noise(dist)
        z = truth[:, 0:2] + rng.normal(0, 0.1, (n, 2))
        if len(seen):
            proj = ukf.project(x[seen], cov[seen], meas.hx)
            x[seen], cov[seen] = ukf.update(x[seen], cov[seen], proj, z[seen], r[seen])
        for i in range(n):
            zi = z[i] if i in seen else None
            ref_x[i], ref_p[i] = linear_kf(
                ref_x[i], ref_p[i], float(dt[i]), motion.acceleration_variance, zi, r[i]
            )
        np.testing.assert_allclose(x, ref_x, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(cov, ref_p, rtol=1e-9, atol=1e-9)


def test_ukf_projection_is_the_exact_innovation_for_linear_models() -> None:
    rng = np.random.default_rng(3)
    ukf = UnscentedKalmanFilter(MerweSigmaPoints(4))
    a = rng.normal(size=(5, 4, 4))
    cov = a @ np.swapaxes(a, 1, 2) + 0.1 * np.eye(4)
    x = rng.normal(size=(5, 4))
    proj = ukf.project(x, cov, PositionMeasurement.hx)
    np.testing.assert_allclose(proj.z, x[:, 0:2], atol=1e-12)
    np.testing.assert_allclose(proj.pzz, cov[:, 0:2, 0:2], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(proj.pxz, cov[:, :, 0:2], rtol=1e-12, atol=1e-12)


def _fx_nonlinear(sigmas: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """A smooth, bounded nonlinear motion (position-dependent forcing)."""
    out = sigmas.copy()
    d = dt[:, None]
    out[..., 0] += d * sigmas[..., 2]
    out[..., 1] += d * sigmas[..., 3]
    out[..., 2] += d * 0.4 * np.sin(sigmas[..., 1])
    out[..., 3] += d * 0.4 * np.cos(sigmas[..., 0])
    return out


def _hx_nonlinear(sigmas: np.ndarray) -> np.ndarray:
    """A bounded nonlinear measurement of position (no angle wrapping)."""
    x, y = sigmas[..., 0], sigmas[..., 1]
    return np.stack([x + 0.3 * np.sin(y), y + 0.3 * np.cos(x)], axis=-1)


MODELS = {
    "linear": (ConstantVelocity.fx, PositionMeasurement.hx),
    "nonlinear": (_fx_nonlinear, _hx_nonlinear),
}


@pytest.mark.parametrize("model", list(MODELS), ids=list(MODELS))
def test_ukf_equals_filterpy_step_by_step(model: str) -> None:
    """Same sigma points (Merwe, alpha=1, beta=2, kappa=0), fx, hx, Q and R as filterpy 2.

    The nonlinear case checks the weights (beta, the centre weight) that a linear model
    cannot see.
    """
    fx, hx = MODELS[model]
    rng = np.random.default_rng(11)
    n, steps = 4, 300
    motion = ConstantVelocity(0.5)
    meas = PositionMeasurement(0.08, 0.002)
    ukf = UnscentedKalmanFilter(MerweSigmaPoints(4, alpha=1.0, beta=2.0, kappa=0.0))
    x = np.column_stack([rng.uniform(1, 6, (n, 2)), rng.normal(0, 0.5, (n, 2))])
    cov = np.stack([np.diag([0.1, 0.1, 1.0, 1.0])] * n)
    refs = []
    for i in range(n):
        f = FilterpyUKF(
            dim_x=4,
            dim_z=2,
            dt=0.0,
            hx=lambda s: hx(s[None, None, :])[0, 0],
            fx=lambda s, dt: fx(s[None, None, :], np.array([dt]))[0, 0],
            points=MerweScaledSigmaPoints(4, alpha=1.0, beta=2.0, kappa=0.0),
        )
        f.x, f.P = x[i].copy(), cov[i].copy()
        refs.append(f)
    truth = x.copy()
    for _ in range(steps):
        dt = rng.uniform(0.005, 0.4, n)
        truth = fx(truth[:, None, :], dt)[:, 0, :]
        q = motion.noise(dt)
        x, cov = ukf.predict(x, cov, dt, fx, q)
        for i, f in enumerate(refs):
            f.Q = q[i]
            f.predict(dt=float(dt[i]))
        np.testing.assert_allclose(x, [f.x for f in refs], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(cov, [f.P for f in refs], rtol=1e-9, atol=1e-9)
        r = meas.noise(rng.uniform(0.5, 8.0, n))
        z = hx(truth[:, None, :])[:, 0, :] + rng.normal(0, 0.08, (n, 2))
        proj = ukf.project(x, cov, hx)
        x, cov = ukf.update(x, cov, proj, z, r)
        for i, f in enumerate(refs):
            f.update(z[i], R=r[i])
        np.testing.assert_allclose(x, [f.x for f in refs], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(cov, [f.P for f in refs], rtol=1e-9, atol=1e-9)


def test_ukf_handles_no_tracks() -> None:
    ukf = UnscentedKalmanFilter(MerweSigmaPoints(4))
    x, cov = ukf.predict(
        np.zeros((0, 4)),
        np.zeros((0, 4, 4)),
        np.zeros(0),
        ConstantVelocity.fx,
        np.zeros((0, 4, 4)),
    )
    assert x.shape == (0, 4)
    assert cov.shape == (0, 4, 4)


# -------------------------------------------- covariances stay SPD


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1),
    q=st.floats(0.01, 20.0),
    sigma=st.floats(0.005, 0.5),
    sigma2=st.floats(0.0, 0.05),
    long_gaps=st.booleans(),
)
def test_ukf_covariances_stay_spd(
    seed: int, q: float, sigma: float, sigma2: float, long_gaps: bool
) -> None:
    rng = np.random.default_rng(seed)
    n = 4
    motion = ConstantVelocity(q)
    meas = PositionMeasurement(sigma, sigma2)
    ukf = UnscentedKalmanFilter(MerweSigmaPoints(4))
    x = np.column_stack([rng.uniform(0, 10, (n, 2)), np.zeros((n, 2))])
    cov = np.stack([np.diag([sigma**2, sigma**2, 2.25, 2.25])] * n)
    for _ in range(150):
        dt = rng.exponential(0.03, n) + 1e-4
        if long_gaps:
            dt = np.where(rng.random(n) < 0.1, rng.uniform(1.0, 5.0, n), dt)
        x, cov = ukf.predict(x, cov, dt, motion.fx, motion.noise(dt))
        assert is_spd(cov)
        z = x[:, 0:2] + rng.normal(0, 3 * sigma + 0.05, (n, 2))
        proj = ukf.project(x, cov, meas.hx)
        x, cov = ukf.update(x, cov, proj, z, meas.noise(rng.uniform(0.3, 10.0, n)))
        assert is_spd(cov)
        assert np.isfinite(x).all()
