"""A sensor's rigid misalignment on the floor, learned from its detections of tracked people.

A calibration a few centimetres and a degree or two off (Munaro et al., *OpenPTrack*,
§4.3) puts one sensor's detections of everybody slightly beside where the other sensors
put them, by an offset that grows with the distance from the sensor (a 2° error is 0.2 m
at 6 m). :class:`RigidAlignment` estimates the floor rotation and translation that best
map a sensor's raw detections onto the fused tracks it was associated with: a weighted
2-D Procrustes fit (closed form: the rotation from the cross-covariance of the centred
point sets, then the translation) over exponentially forgotten sums, so it follows a
sensor that is bumped. The rotation is only estimated once the matched positions spread
over enough of the floor to tell a rotation from a shift.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np


def rotation(theta: float) -> np.ndarray:
    """The 2-D rotation matrix of ``theta`` radians."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def procrustes_angle(cross: np.ndarray) -> float:
    """The rotation (radians) best mapping centred points onto others (2-D Procrustes).

    ``cross`` is their ``2 x 2`` cross-covariance, ``sum(src_i dst_i^T)``.
    """
    return math.atan2(cross[0, 1] - cross[1, 0], cross[0, 0] + cross[1, 1])


def rigid_fit(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray]:
    """Least-squares rotation and translation mapping ``src (k, 2)`` onto ``dst``."""
    sc, dc = src.mean(axis=0), dst.mean(axis=0)
    theta = procrustes_angle((src - sc).T @ (dst - dc))
    return theta, dc - rotation(theta) @ sc


@dataclass
class RigidAlignment:
    """Exponentially forgotten sums of matched pairs, and the rigid map they give.

    Parameters
    ----------
    memory : float
        Effective number of pairs remembered.
    min_spread_m2 : float
        Least variance (sum over both axes) of the matched raw positions before the
        rotation is estimated.
    fitted_weight : float
        The remembered weight when the map was last fitted: how many pairs it rests on.
    """

    memory: float = 2000.0
    min_spread_m2: float = 1.0
    weight: float = 0.0
    sum_z: np.ndarray = field(default_factory=lambda: np.zeros(2))
    sum_x: np.ndarray = field(default_factory=lambda: np.zeros(2))
    sum_zz: np.ndarray = field(default_factory=lambda: np.zeros(2))
    sum_zx: np.ndarray = field(default_factory=lambda: np.zeros((2, 2)))
    theta: float = 0.0
    fitted_weight: float = 0.0
    shift: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def copy(self) -> RigidAlignment:
        """An independent copy."""
        return replace(
            self,
            sum_z=self.sum_z.copy(),
            sum_x=self.sum_x.copy(),
            sum_zz=self.sum_zz.copy(),
            sum_zx=self.sum_zx.copy(),
            shift=self.shift.copy(),
        )

    def apply(self, z: np.ndarray) -> np.ndarray:
        """Map raw positions ``(n, 2)`` into the fused frame."""
        if self.theta == 0.0:
            return z + self.shift
        return z @ rotation(self.theta).T + self.shift

    def invert(self, x: np.ndarray) -> np.ndarray:
        """Map positions of the fused frame back to raw ones."""
        return (x - self.shift) @ rotation(self.theta)

    def add(self, z_raw: np.ndarray, x: np.ndarray) -> None:
        """Remember pairs: raw detections ``(k, 2)`` and the fused positions they matched."""
        keep = (1.0 - 1.0 / self.memory) ** len(z_raw)
        self.weight = keep * self.weight + len(z_raw)
        self.sum_z = keep * self.sum_z + z_raw.sum(axis=0)
        self.sum_x = keep * self.sum_x + x.sum(axis=0)
        self.sum_zz = keep * self.sum_zz + (z_raw**2).sum(axis=0)
        self.sum_zx = keep * self.sum_zx + z_raw.T @ x

    def then(self, theta: float, shift: np.ndarray) -> None:
        """Follow the map by a rigid move of the fused frame (``x -> R(theta) x + shift``).

        The remembered targets move with it, so the pairs keep their weight.
        """
        rot = rotation(theta)
        self.sum_x = rot @ self.sum_x + self.weight * shift
        self.sum_zx = self.sum_zx @ rot.T + np.outer(self.sum_z, shift)
        self.theta += theta
        self.shift = rot @ self.shift + shift

    def fit(self) -> None:
        """Update the rotation and translation from the remembered pairs."""
        if self.weight <= 0:
            return
        self.fitted_weight = self.weight
        zbar, xbar = self.sum_z / self.weight, self.sum_x / self.weight
        spread = float(self.sum_zz.sum() / self.weight - zbar @ zbar)
        if spread >= self.min_spread_m2:
            m = self.sum_zx / self.weight - np.outer(zbar, xbar)
            self.theta = procrustes_angle(m)
        self.shift = xbar - rotation(self.theta) @ zbar

    def centroid(self) -> np.ndarray:
        """Mean raw position of the remembered pairs (where the map was learned)."""
        return self.sum_z / self.weight if self.weight > 0 else np.zeros(2)
