"""A noise profile's centroid error: white, persistent (per person and sensor) and outliers.

Real people detectors do not err independently frame to frame: the same pose, the same
partial view of a body and the same segmentation mistakes put one sensor's detections of
a person consistently off for a while, and off differently from another sensor's. A
:class:`CentroidError` is one sensor's state of that error: per person, an
Ornstein-Uhlenbeck process on the floor (stationary standard deviation
``correlated_sigma_m`` per axis, time constant ``correlation_time_s``), plus a white
term and rare outliers (:class:`~openptrack_py.sim.profiles.NoiseProfile`).
"""

from __future__ import annotations

import math

import numpy as np

from openptrack_py.sim.profiles import NoiseProfile
from openptrack_py.sim.sensor_spec import SensorNoise

REFERENCE_DISTANCE_M = 3.5
"""Distance at which a profile's persistent and outlier terms have their nominal size.

The middle of the 2-5 m of the childcare paper's measurement; farther away they grow as
the sensor type's along-ray depth noise does (Kinect v1's with the distance squared).
"""


class CentroidError:
    """One sensor's centroid error of the people it detects, under a noise profile.

    Parameters
    ----------
    profile : NoiseProfile
        Sizes of the white, persistent and outlier terms and the noise scale.
    noise : SensorNoise
        The sensor type's noise model (for the growth with distance).
    rng : numpy.random.Generator
        This sensor's generator for these terms alone.
    """

    def __init__(self, profile: NoiseProfile, noise: SensorNoise, rng: np.random.Generator):
        self.profile = profile
        self.noise = noise
        self.rng = rng
        self._reference_sigma = float(noise.depth_sigma_at(REFERENCE_DISTANCE_M))
        # person id -> (time of the last draw, unit-variance 2-vector state)
        self._state: dict[int, tuple[float, np.ndarray]] = {}

    def growth(self, distance_m: np.ndarray) -> np.ndarray:
        """Factor (>= 1) of the persistent and outlier terms at ``distance_m``."""
        ratio = self.noise.depth_sigma_at(distance_m) / max(self._reference_sigma, 1e-9)
        return np.maximum(ratio, 1.0)

    def sample(self, t: float, ids: np.ndarray, distance_m: np.ndarray) -> np.ndarray:
        """The floor offsets ``(n, 2)`` of this frame's detections of people ``ids``.

        Parameters
        ----------
        t : float
            Scenario time, seconds.
        ids : ndarray of int
            Ground-truth person id of each detection.
        distance_m : ndarray
            Each person's distance from the sensor, metres.
        """
        p = self.profile
        rng = self.rng
        n = len(ids)
        white = rng.normal(0.0, 1.0, (n, 2))
        innovation = rng.normal(0.0, 1.0, (n, 2))
        outlier = rng.random(n) < p.outlier_probability
        jump = rng.normal(0.0, 1.0, (n, 2))
        persistent = np.empty((n, 2))
        for j, pid in enumerate(ids.tolist()):
            last = self._state.get(pid)
            if last is None:
                z = innovation[j]  # a person first seen: the stationary distribution
            else:
                rho = math.exp(-max(t - last[0], 0.0) / p.correlation_time_s)
                z = rho * last[1] + math.sqrt(1.0 - rho * rho) * innovation[j]
            self._state[pid] = (t, z)
            persistent[j] = z
        grow = self.growth(distance_m)[:, None]
        offset = p.body_sigma_m * white + p.correlated_sigma_m * grow * persistent
        offset += outlier[:, None] * (p.outlier_sigma_m * grow * jump)
        return p.noise_scale * offset
