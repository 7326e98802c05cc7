"""A noise profile's error of measured heights: a tilted floor and the walking gait.

A people detector on a depth sensor measures a person's height as the top of their
cluster above the floor plane it was given. Two errors besides the depth noise
(:data:`~openptrack_py.sim.sensor_spec.SENSOR_NOISE`'s ``height_sigma_m``) make heights
differ between sensors and over time, so that height is an honest, not a perfect, cue of
who is who:

* the floor plane a sensor measures from is tilted a little (``floor_tilt_deg``): its
  error in height grows linearly with the distance from the sensor, in the direction of
  the tilt, and is the same for everyone that sensor sees there;
* walking people are lower than standing ones, and bob: the body's centre of mass, and
  with it the head, rises and falls about 5 cm peak to peak once per step (Saunders,
  Inman and Eberhart, *The major determinants in normal and pathological gait*, 1953;
  Perry and Burnfield, *Gait Analysis*), highest in mid-stance, near the standing
  height. The rise and fall grow with walking speed (``gait_bob_m`` at
  :data:`WALKING_SPEED_M_S`) and are the person's own, the same for every sensor.
"""

from __future__ import annotations

import math

import numpy as np

from openptrack_py.sim.profiles import NoiseProfile

WALKING_SPEED_M_S = 1.3
"""Usual adult walking speed (about 1.3-1.4 m/s; Bohannon, *Comfortable and maximum
walking speed of adults aged 20-79 years*, 1997), at which the bob has its full size."""
STEP_HZ = 1.8
"""Steps per second of normal walking (a cadence of about 105-115 steps per minute)."""
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


class HeightError:
    """One sensor's error of the heights it measures, under a noise profile.

    Parameters
    ----------
    profile : NoiseProfile
        ``floor_tilt_deg`` (range of the tilt, drawn once) and ``gait_bob_m``.
    origin_xy : ndarray
        The sensor's position on the floor, ``(2,)``.
    rng : numpy.random.Generator
        This sensor's generator for these terms alone.
    """

    def __init__(self, profile: NoiseProfile, origin_xy: np.ndarray, rng: np.random.Generator):
        tilt = math.radians(float(rng.uniform(*profile.floor_tilt_deg)))
        direction = float(rng.uniform(0.0, 2.0 * math.pi))
        self.gradient = math.tan(tilt) * np.array([math.cos(direction), math.sin(direction)])
        """Height error per metre of floor distance from the sensor, ``(2,)``."""
        self.origin = np.asarray(origin_xy, dtype=float)
        self.bob_m = profile.gait_bob_m

    def sample(self, t: float, ids: np.ndarray, pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
        """The height offsets ``(n,)`` of this frame's detections of people ``ids``.

        Parameters
        ----------
        t : float
            Time of the frame, seconds.
        ids : ndarray of int
            Who each detection is (their gait's phase is their own).
        pos, vel : ndarray
            ``(n, 2)`` their true floor positions (m) and velocities (m/s).
        """
        out = (pos - self.origin) @ self.gradient
        if self.bob_m > 0:
            stride = np.minimum(np.linalg.norm(vel, axis=1) / WALKING_SPEED_M_S, 1.0)
            phase = 2.0 * math.pi * ((np.asarray(ids, dtype=float) * _GOLDEN) % 1.0)
            # 0 at the top of a step (mid-stance), -2 bob at the bottom (double support)
            out = out - self.bob_m * stride * (1.0 - np.cos(2.0 * math.pi * STEP_HZ * t + phase))
        return out
