"""What a detection measures of a track's state, and how noisy it is."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from openptrack_py.tracking.state import DetectionArrays, TrackTable


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

    def position_noise(self, distance: np.ndarray) -> np.ndarray:
        """Same as :meth:`noise`: the whole measurement is the position."""
        return self.noise(distance)

    def pair_measurements(
        self, dets: DetectionArrays, table: TrackTable, t: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Every track sees each detection's position with the same noise."""
        n = len(table)
        z = np.broadcast_to(dets.xy, (n, *dets.xy.shape))
        r = np.broadcast_to(self.noise(dets.distance), (n, len(dets), 2, 2))
        return z, r


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

    def position_noise(self, distance: np.ndarray) -> np.ndarray:
        """Noise of the position part alone."""
        return self.position.noise(distance)

    def pair_measurements(
        self, dets: DetectionArrays, table: TrackTable, t: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Position plus the velocity from each track's remembered past to each detection."""
        horizon = np.minimum(self.horizon_s, t - table.first_seen)
        usable = horizon >= self.min_horizon_s
        past = np.array(
            [
                _past_position(table, i, t - max(h, self.min_horizon_s))
                for i, h in enumerate(horizon)
            ]
        ).reshape(-1, 2)
        tau = np.maximum(horizon, self.min_horizon_s)
        vel = (dets.xy[None, :, :] - past[:, None, :]) / tau[:, None, None]
        z = np.concatenate([np.broadcast_to(dets.xy, vel.shape), vel], axis=2)
        return z, self.noise(dets.distance, usable)

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


def _past_position(table: TrackTable, row: int, when: float) -> np.ndarray:
    """Track ``row``'s position at ``when``, interpolated in its remembered history."""
    times, xy = table.hist_t[row], table.hist_xy[row]
    valid = times > -np.inf
    if not valid.any():
        return table.x[row, 0:2]
    order = np.argsort(times[valid])
    ts, ps = times[valid][order], xy[valid][order]
    return np.array([np.interp(when, ts, ps[:, 0]), np.interp(when, ts, ps[:, 1])])
