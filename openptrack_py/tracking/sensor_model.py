"""What the tracker learns about each sensor while it runs: noise, bias and coverage.

Real detections are noisier than any fixed model of them, and each sensor errs in its
own way: a far or partly occluded view, a calibration a few centimetres and a degree or
two off (Munaro et al., *OpenPTrack*, §4.3, report such disagreements before refinement;
its users report "two ids tracking the same person, offset by about 10 cm, at the
boundary between two cameras"). :class:`OnlineSensorModel` estimates, per sensor, from
the innovations of the confirmed tracks it updates:

* a **noise scale** ``s``: the sensor's measurement covariance is ``s`` times the
  configured model. Innovation-based adaptive estimation (Mehra, 1970) with the gate
  taken into account: the squared Mahalanobis distances of gated pairs are samples of a
  chi-square *truncated at the gate*, so ``s`` is their maximum-likelihood scale under
  that truncation (a plain average of gated distances can never exceed the gate and
  would never widen it). Only unambiguous pairs count (one detection in the track's
  gate, one track in the detection's), ``s`` is bounded, and it is re-estimated every
  few dozen samples from the last few hundred. A sensor noisier than configured widens
  its own gate instead of spawning tracks.
* a **bias**: the mean offset of the sensor's detections from the fused tracks, learned
  only where at least two sensors see the track (one sensor alone defines its track),
  bounded, and removed from its detections before association. What one bias cannot
  tell from a shift of the whole world is fixed by keeping the sample-weighted mean of
  all sensors' biases at zero. This is the quantity calibration refinement needs.
* a **coverage** map: the floor cells where a sensor has ever reported a detection.
  It tells which sensors should see a track, so a person seen by only one of three
  overlapping sensors counts as weaker evidence. It is a union over the batches seen,
  the same in whatever order they are applied, so replays need not restore it.

:class:`StaticSensorModel` learns nothing (every sensor as configured).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import minimize_scalar

from openptrack_py.tracking.state import DetectionArrays

COVERAGE_CELL_M = 0.5
"""Side of a coverage cell, metres."""


@dataclass
class _SensorState:
    """Everything learned about one sensor (copied whole by :meth:`snapshot`)."""

    scale: float = 1.0
    bias: np.ndarray = field(default_factory=lambda: np.zeros(2))
    bias_samples: float = 0.0
    # ring buffer of (u, c): gated distances rescaled to the model, and their truncation
    u: np.ndarray = field(default_factory=lambda: np.zeros(0))
    c: np.ndarray = field(default_factory=lambda: np.zeros(0))
    head: int = 0
    since_fit: int = 0

    def copy(self) -> _SensorState:
        return replace(self, bias=self.bias.copy(), u=self.u.copy(), c=self.c.copy())


def _chi2_logpdf_logcdf(x: np.ndarray, dof: int) -> tuple[np.ndarray, np.ndarray]:
    """Closed forms of the chi-square log density and log distribution for 2 or 4 dof."""
    half = x / 2.0
    if dof == 2:
        return -math.log(2.0) - half, np.log(-np.expm1(-half))
    if dof == 4:
        with np.errstate(divide="ignore"):
            logpdf = np.log(x / 4.0) - half
        return logpdf, np.log(-np.expm1(-half) - half * np.exp(-half))
    raise ValueError(f"truncated_scale: dof must be 2 or 4, got {dof}")


def truncated_scale(u: np.ndarray, c: np.ndarray, dof: int, bounds: tuple[float, float]) -> float:
    """Maximum-likelihood scale ``s`` of samples ``u ~ s * chi2(dof)`` truncated at ``c``.

    Parameters
    ----------
    u : ndarray
        Samples (squared Mahalanobis distances under the unit-scale model).
    c : ndarray
        Each sample's truncation point (the gate, under the unit-scale model).
    dof : int
        Degrees of freedom: 2 (a floor position) or 4 (position and velocity).
    bounds : (float, float)
        Least and largest scale returned.
    """

    def nll(log_s: float) -> float:
        s = math.exp(log_s)
        logpdf, _ = _chi2_logpdf_logcdf(u / s, dof)
        _, logcdf = _chi2_logpdf_logcdf(c / s, dof)
        return -float(np.sum(logpdf - log_s - logcdf))

    lo, hi = math.log(bounds[0]), math.log(bounds[1])
    res = minimize_scalar(nll, bounds=(lo, hi), method="bounded", options={"xatol": 1e-3})
    return float(min(max(math.exp(res.x), bounds[0]), bounds[1]))


class OnlineSensorModel:
    """Per-sensor noise scale, bias and coverage, learned from the tracker's updates.

    Parameters
    ----------
    adapt_noise : bool
        Estimate each sensor's noise scale.
    estimate_bias : bool
        Estimate and remove each sensor's bias.
    scale_bounds : (float, float)
        Least and largest noise scale (on the covariance).
    max_bias_m : float
        Largest bias, metres.
    bias_rate : float
        Weight of one sample in the bias's exponential average.
    window : int
        Gated distances kept per sensor for the noise scale.
    refit_every : int
        New samples between two noise-scale fits.
    min_samples : int
        Samples needed before the first fit.
    """

    def __init__(
        self,
        *,
        adapt_noise: bool = True,
        estimate_bias: bool = True,
        scale_bounds: tuple[float, float] = (0.25, 25.0),
        max_bias_m: float = 0.5,
        bias_rate: float = 0.01,
        window: int = 300,
        refit_every: int = 30,
        min_samples: int = 60,
    ) -> None:
        if not 0 < scale_bounds[0] <= 1.0 <= scale_bounds[1]:
            raise ValueError(
                f"OnlineSensorModel: scale_bounds must satisfy 0 < low <= 1 <= high, "
                f"got {scale_bounds}"
            )
        self.adapt_noise = adapt_noise
        self.estimate_bias = estimate_bias
        self.scale_bounds = scale_bounds
        self.max_bias_m = max_bias_m
        self.bias_rate = bias_rate
        self.window = window
        self.refit_every = refit_every
        self.min_samples = min_samples
        self._sensors: dict[str, _SensorState] = {}
        self._coverage: dict[str, set[tuple[int, int]]] = {}

    # ------------------------------------------------------------------ state

    def snapshot(self) -> tuple[dict[str, _SensorState], dict[str, set[tuple[int, int]]]]:
        """The learned noise and bias of every sensor, and the coverage.

        The coverage is shared, not copied: it only ever grows by the cells of the
        batches seen, the same whatever their order, so a replay re-adds what it has.
        """
        return {name: st.copy() for name, st in self._sensors.items()}, self._coverage

    def restore(
        self, state: tuple[dict[str, _SensorState], dict[str, set[tuple[int, int]]]]
    ) -> None:
        """Return to a snapshot."""
        self._sensors = {name: st.copy() for name, st in state[0].items()}
        self._coverage = state[1]

    # ------------------------------------------------------------------ queries

    def noise_scale(self, sensor_id: str) -> float:
        """Factor on the configured measurement covariance of this sensor."""
        st = self._sensors.get(sensor_id)
        return st.scale if st is not None else 1.0

    def bias(self, sensor_id: str) -> np.ndarray:
        """Estimated bias of a sensor (metres, world frame)."""
        st = self._sensors.get(sensor_id)
        return st.bias.copy() if st is not None else np.zeros(2)

    def summary(self) -> dict[str, dict[str, float]]:
        """Per sensor: noise scale and bias, for stats and logs."""
        return {
            name: {"noise_scale": st.scale, "bias_x_m": st.bias[0], "bias_y_m": st.bias[1]}
            for name, st in sorted(self._sensors.items())
        }

    def correct(self, dets: DetectionArrays) -> DetectionArrays:
        """The detections with their sensor's bias removed; marks the sensor's coverage."""
        if len(dets):
            cells = self._coverage.setdefault(dets.sensor_id, set())
            cells.update(map(tuple, np.floor(dets.xy / COVERAGE_CELL_M).astype(int).tolist()))
        st = self._sensors.get(dets.sensor_id)
        if st is None or not st.bias.any() or not len(dets):
            return dets
        return replace(dets, xy=dets.xy - st.bias)

    def covers(self, sensor_id: str, xy: np.ndarray) -> np.ndarray:
        """Mask of floor positions ``xy (n, 2)`` where this sensor has reported people."""
        cells = self._coverage.get(sensor_id)
        if not cells or not len(xy):
            return np.zeros(len(xy), dtype=bool)
        keys = np.floor(xy / COVERAGE_CELL_M).astype(int).tolist()
        return np.array([tuple(k) in cells for k in keys], dtype=bool)

    # ----------------------------------------------------------------- learning

    def learn(
        self,
        sensor_id: str,
        innovation: np.ndarray,
        d2: np.ndarray,
        gate: float,
        multi_sensor: np.ndarray,
    ) -> None:
        """Learn from this batch's unambiguous updates of confirmed tracks.

        Parameters
        ----------
        sensor_id : str
            The batch's sensor.
        innovation : ndarray
            ``(k, 2)`` detection minus predicted position (bias already removed).
        d2 : ndarray
            ``(k,)`` their squared Mahalanobis distances under the scaled noise.
        gate : float
            The gate they passed (on ``d2``).
        multi_sensor : ndarray
            ``(k,)`` whether another sensor also sees the track (bias is only learned
            there).
        """
        if not len(d2):
            return
        st = self._sensors.setdefault(sensor_id, _SensorState())
        if self.adapt_noise:
            self._add_samples(st, d2 * st.scale, gate * st.scale)
        if self.estimate_bias and multi_sensor.any():
            self._learn_bias(sensor_id, st, innovation[multi_sensor])

    def _add_samples(self, st: _SensorState, u: np.ndarray, c: float) -> None:
        if len(st.u) < self.window:
            st.u = np.concatenate([st.u, u])[-self.window :]
            st.c = np.concatenate([st.c, np.full(len(u), c)])[-self.window :]
        else:
            idx = (st.head + np.arange(len(u))) % self.window
            st.u[idx] = u
            st.c[idx] = c
            st.head = int((st.head + len(u)) % self.window)
        st.since_fit += len(u)
        if len(st.u) >= self.min_samples and st.since_fit >= self.refit_every:
            st.since_fit = 0
            st.scale = truncated_scale(st.u, st.c, 2, self.scale_bounds)

    def _learn_bias(self, sensor_id: str, st: _SensorState, innovation: np.ndarray) -> None:
        # stochastic approximation: the bias moves until the corrected innovations
        # average zero (a capped step, so a batch of many tracks cannot overshoot)
        step = min(self.bias_rate * len(innovation), 0.5)
        st.bias = st.bias + step * innovation.mean(axis=0)
        st.bias_samples += len(innovation)
        norm = float(np.hypot(*st.bias))
        if norm > self.max_bias_m:
            st.bias *= self.max_bias_m / norm
        # gauge: a shift of every sensor at once is invisible; keep the weighted mean at 0
        learned = [s for s in self._sensors.values() if s.bias_samples > 0]
        if len(learned) >= 2:
            weights = np.array([s.bias_samples for s in learned])
            mean = np.average([s.bias for s in learned], axis=0, weights=weights)
            for s in learned:
                s.bias = s.bias - mean


class StaticSensorModel:
    """Every sensor exactly as configured: no noise scale, no bias, no coverage."""

    def noise_scale(self, sensor_id: str) -> float:
        """Always 1."""
        return 1.0

    def correct(self, dets: DetectionArrays) -> DetectionArrays:
        """The detections unchanged."""
        return dets

    def covers(self, sensor_id: str, xy: np.ndarray) -> np.ndarray:
        """No coverage is known."""
        return np.zeros(len(xy), dtype=bool)

    def learn(
        self,
        sensor_id: str,
        innovation: np.ndarray,
        d2: np.ndarray,
        gate: float,
        multi_sensor: np.ndarray,
    ) -> None:
        """Nothing to learn."""
