"""What a detection measures of a track's state, and how noisy it is."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PositionMeasurement:
    """A detection measures the track's floor position ``[x, y]``.

    Noise is isotropic with standard deviation ``sigma_m + sigma_per_m2 * d**2`` at
    detection distance ``d`` (depth noise of structured-light sensors grows with the
    square of the range; time-of-flight sensors are nearly flat).

    Parameters
    ----------
    sigma_m : float
        Standard deviation at zero distance, metres.
    sigma_per_m2 : float
        Growth per squared metre of distance.
    """

    sigma_m: float
    sigma_per_m2: float = 0.0

    dim = 2

    @staticmethod
    def hx(sigmas: np.ndarray) -> np.ndarray:
        """Measurement of sigma points ``(N, k, 4) -> (N, k, 2)``."""
        return sigmas[..., 0:2]

    def noise(self, distance: np.ndarray) -> np.ndarray:
        """Noise covariances ``(M, 2, 2)`` of detections at ``distance (M,)`` metres."""
        sigma = self.sigma_m + self.sigma_per_m2 * np.asarray(distance, dtype=float) ** 2
        return (sigma**2)[:, None, None] * np.eye(2)


@dataclass(frozen=True)
class PositionVelocityMeasurement:
    """A detection measures position and, through the track's past, velocity.

    OpenPTrack's ``velocity_in_motion_term``: the velocity measurement is the
    displacement of the detection from the track's own estimate about ``horizon_s``
    earlier, divided by that time. Tracks younger than ``min_horizon_s`` get an
    uninformative velocity (huge noise) so only their position counts.

    Parameters
    ----------
    position : PositionMeasurement
        Position part.
    velocity_sigma_mps : float
        Standard deviation of the velocity measurement.
    horizon_s : float
        How far back the displacement is measured.
    min_horizon_s : float
        Shortest usable history.
    """

    position: PositionMeasurement
    velocity_sigma_mps: float = 0.5
    horizon_s: float = 1.0
    min_horizon_s: float = 0.2

    dim = 4

    @staticmethod
    def hx(sigmas: np.ndarray) -> np.ndarray:
        """Measurement of sigma points ``(N, k, 4) -> (N, k, 4)``."""
        return sigmas[..., 0:4]

    def noise(self, distance: np.ndarray, usable: np.ndarray) -> np.ndarray:
        """Noise ``(N, M, 4, 4)`` for tracks with ``usable (N,)`` history."""
        pos = self.position.noise(distance)  # (M, 2, 2)
        n, m = len(usable), len(pos)
        out = np.zeros((n, m, 4, 4))
        out[:, :, 0:2, 0:2] = pos[None]
        var = np.where(usable, self.velocity_sigma_mps**2, 1.0e4)
        out[:, :, 2, 2] = var[:, None]
        out[:, :, 3, 3] = var[:, None]
        return out
