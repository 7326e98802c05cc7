"""Constant-velocity motion on the floor."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Q = q * (dt^3/3 * _Q_TERMS[0] + dt^2/2 * _Q_TERMS[1] + dt * _Q_TERMS[2])
_Q_TERMS = np.zeros((3, 4, 4))
for _i in (0, 1):
    _Q_TERMS[0, _i, _i] = 1.0
    _Q_TERMS[1, _i, _i + 2] = _Q_TERMS[1, _i + 2, _i] = 1.0
    _Q_TERMS[2, _i + 2, _i + 2] = 1.0


@dataclass(frozen=True)
class ConstantVelocity:
    """State ``[x, y, vx, vy]`` moving at constant velocity, driven by white acceleration.

    The process noise is the exact discretisation of continuous white acceleration with
    spectral density ``q`` over the real, possibly irregular, step ``dt``::

        Q = q * [[dt^3/3 I, dt^2/2 I],
                 [dt^2/2 I, dt     I]]

    Parameters
    ----------
    acceleration_variance : float
        Spectral density ``q``, m^2/s^3.
    """

    acceleration_variance: float

    def __post_init__(self) -> None:
        if not self.acceleration_variance > 0:
            raise ValueError(
                "ConstantVelocity: acceleration_variance must be > 0, "
                f"got {self.acceleration_variance}"
            )

    @staticmethod
    def fx(sigmas: np.ndarray, dt: np.ndarray) -> np.ndarray:
        """Move sigma points ``(N, k, 4)`` forward by ``dt (N,)``."""
        out = sigmas.copy()
        out[..., 0:2] += dt[:, None, None] * sigmas[..., 2:4]
        return out

    def noise(self, dt: np.ndarray) -> np.ndarray:
        """Process noise ``(N, 4, 4)`` for steps ``dt``."""
        dt = np.abs(np.atleast_1d(np.asarray(dt, dtype=float)))
        powers = np.stack([dt**3 / 3.0, dt**2 / 2.0, dt], axis=1)  # (N, 3)
        return self.acceleration_variance * np.einsum("nk,kij->nij", powers, _Q_TERMS)
