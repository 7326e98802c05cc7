"""What the tracker learns about each sensor while it runs: noise, bias and coverage.

Real detections are noisier than any fixed model of them, and each sensor errs in its
own way: a far or partly occluded view, a calibration a few centimetres and a degree or
two off (Munaro et al., *OpenPTrack*, §4.3, report such disagreements before refinement;
its users report "two ids tracking the same person, offset by about 10 cm, at the
boundary between two cameras"). :class:`OnlineSensorModel` estimates, per sensor, from
the innovations of the confirmed tracks it updates:

* a **noise scale** ``s(d)``: the sensor's measurement covariance is ``s`` times the
  configured model, ``s`` estimated in bands of distance from the sensor (how a real
  detector's error grows with range is rarely the configured curve) and interpolated
  between them. Innovation-based adaptive estimation (Mehra, 1970) with the gate
  taken into account: the squared Mahalanobis distances of gated pairs are samples of a
  chi-square *truncated at the gate*, so ``s`` is their maximum-likelihood scale under
  that truncation (a plain average of gated distances can never exceed the gate and
  would never widen it). Only unambiguous pairs count (one detection in the track's
  gate, one confirmed track in the detection's: a tentative track beside the person,
  which a noisier sensor's own detections start, does not stop the learning that would
  end such births), ``s`` is bounded, and it is re-estimated every
  few dozen samples from the last few hundred, with the track's own uncertainty
  taken into account (the innovation's variance is the track's plus the sensor's). A
  sensor noisier than configured widens its own gate instead of spawning tracks.
* an **alignment**: the floor rotation and translation that map the sensor's detections
  onto the fused tracks (:class:`~openptrack_py.tracking.alignment.RigidAlignment`),
  learned only where at least two sensors see the track (one sensor alone defines its
  track), bounded, and applied to its detections before association. A rotation or
  shift of every sensor at once is invisible; it is fixed by keeping the sensors' mean
  map the identity. This is the quantity calibration refinement needs. Until it is
  learned, a calibration may be off by more than a gate (the OpenPTrack paper reports
  5-20 cm and 1-3 degrees before refinement): each sensor would then start its own
  track of every person, no track would be fed by two sensors, and nothing would be
  learned. So, given the calibration's own uncertainty (``calibration_sigma``), a
  detection compared with a track another sensor fed last has both sensors' unlearned
  misalignment added to its noise, ``sigma_m^2 + (sigma_yaw d)^2`` per axis and sensor
  at the detection's distance ``d``: the prior, shrunk to its posterior by the ``n``
  pairs the sensor's fitted alignment rests on (:data:`ALIGNMENT_PAIR_VAR_M2`). A
  sensor's detections are never widened against its own tracks: its own error is
  common to both. With ``twins``, a sensor whose *share* is low (of its tracks where
  others see, few that others feed too) learns it from the rigid map its twin tracks
  agree on (:mod:`~openptrack_py.tracking.twins`).
* a **clutter density**: how many of the sensor's detections no track takes, per
  frame and square metre of the floor it covers. A track may only take a detection
  that it explains better than clutter would (its likelihood above that density), so a
  lost track whose gate has grown wide does not jump onto a false detection across
  the room, while in a clean room it finds its person again from afar.
* a **coverage** map: the floor cells where a sensor has reported at least a few
  detections. It tells which sensors should see a track, so a person seen by only one
  of three overlapping sensors counts as weaker evidence. Each batch counts once (by
  its sequence number), in whatever order batches are applied, so replays need not
  restore it.

:class:`~openptrack_py.tracking.static_sensors.StaticSensorModel` learns nothing (every
sensor as configured).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import minimize_scalar

from openptrack_py.tracking.alignment import RigidAlignment, rigid_fit, rotation
from openptrack_py.tracking.coverage import COVERAGE_CELL_M, Coverage
from openptrack_py.tracking.state import SENSOR_SLOTS, DetectionArrays, TrackTable
from openptrack_py.tracking.twins import TwinAligner, TwinLesson

NOISE_BANDS_M = np.array([0.0, 3.0, 5.0, 7.0, np.inf])
"""Edges of the distance bands in which a sensor's noise scale is estimated."""
NOISE_BAND_CENTRES_M = np.array([2.0, 4.0, 6.0, 8.0])
"""Where each band's scale applies fully (linear in between, constant outside)."""
CLUTTER_RATE = 0.01
"""Weight of one frame in a sensor's average of unexplained detections."""
SHARED_RATE = 0.01
"""Weight of one update in a sensor's share of tracks other sensors feed too."""
UNSHARED_BELOW = 0.5
"""A sensor whose share is below this (most of its tracks where others see have no
other sensor's detections) may have its calibration learned from twins: a calibrated
sensor's share is about 1, one whose every person has a twin about 0."""
MIN_CLUTTER_DENSITY = 1e-3
"""Least clutter density assumed, per frame and square metre."""


@dataclass(frozen=True)
class SensorUpdates:
    """One batch's unambiguous updates of confirmed tracks, for a sensor model to learn.

    Parameters
    ----------
    sensor_id : str
        The batch's sensor.
    detected : ndarray
        ``(k, 2)`` the detections, as corrected by the sensor model.
    predicted : ndarray
        ``(k, 2)`` the predicted positions of the tracks they were associated with.
    distance : ndarray
        ``(k,)`` the detections' distances from the sensor, metres.
    track_var : ndarray
        ``(k,)`` the tracks' predicted position variance, per axis.
    model_var : ndarray
        ``(k,)`` the configured (unscaled) measurement variance, per axis.
    gate : float
        The chi-square threshold the pairs passed.
    multi_sensor : ndarray
        ``(k,)`` whether another sensor also sees each track.
    """

    sensor_id: str
    detected: np.ndarray
    predicted: np.ndarray
    distance: np.ndarray
    track_var: np.ndarray
    model_var: np.ndarray
    gate: float
    multi_sensor: np.ndarray


@dataclass
class _SensorState:
    """Everything learned about one sensor (copied whole by :meth:`snapshot`)."""

    scales: np.ndarray = field(default_factory=lambda: np.ones(len(NOISE_BAND_CENTRES_M)))
    unexplained_per_frame: float = 0.0
    align: RigidAlignment = field(default_factory=RigidAlignment)
    since_align: int = 0
    shared: float = 0.0  # share of its tracks where others see that others feed too
    # ring buffer of gated innovations: |nu|^2, track variance, model variance, cut, range
    samples: np.ndarray = field(default_factory=lambda: np.zeros((0, 5)))
    head: int = 0
    since_fit: int = 0
    batches_since_fit: int = 0

    def copy(self) -> _SensorState:
        return replace(
            self, scales=self.scales.copy(), align=self.align.copy(), samples=self.samples.copy()
        )

    def scale_at(self, distance: np.ndarray) -> np.ndarray:
        """The noise scale at each distance (interpolated between the bands)."""
        return np.exp(np.interp(distance, NOISE_BAND_CENTRES_M, np.log(self.scales)))


def gated_noise_scale(samples: np.ndarray, bounds: tuple[float, float]) -> float:
    """Maximum-likelihood noise scale ``s`` from gated 2-D innovations.

    Each sample is ``(q, p, r, c)``: the squared norm ``q = |nu|^2`` of an innovation
    whose covariance is ``(p + s r) I`` (``p`` the track's predicted position variance,
    ``r`` the configured measurement variance, both per axis), kept only because
    ``q <= c`` (the gate). So ``q / (p + s r)`` is chi-square with 2 degrees of freedom,
    truncated at ``c / (p + s r)``: the likelihood accounts for the gate, without which
    the gated samples could never tell that the gate is too narrow.

    Parameters
    ----------
    samples : ndarray
        ``(n, 4+)`` rows ``(q, p, r, c, ...)``.
    bounds : (float, float)
        Least and largest scale returned.
    """
    q, p, r, c = samples[:, 0:4].T

    def nll(log_s: float) -> float:
        two_var = 2.0 * (p + math.exp(log_s) * r)
        kept = -np.expm1(-c / two_var)  # chi2(2) distribution at the cut
        return float(np.sum(np.log(two_var) + q / two_var + np.log(np.maximum(kept, 1e-300))))

    lo, hi = math.log(bounds[0]), math.log(bounds[1])
    res = minimize_scalar(nll, bounds=(lo, hi), method="bounded", options={"xatol": 1e-3})
    return float(min(max(math.exp(res.x), bounds[0]), bounds[1]))


ALIGNMENT_PAIR_VAR_M2 = 0.3
"""What one matched pair tells of a sensor's misalignment: variance per axis, m^2.

A detection's error is about 0.1 m per axis, and it persists for about a second (a
detector's centroid sits consistently off on one body), so at 30 frames a second some
30 pairs make one independent look: ``0.1^2 * 30``. After ``n`` pairs the misalignment
is known to ``1 / (1 / prior + n / ALIGNMENT_PAIR_VAR_M2)``, the prior's posterior."""


class OnlineSensorModel:
    """Per-sensor noise scale, bias and coverage, learned from the tracker's updates.

    Parameters
    ----------
    adapt_noise : bool
        Estimate each sensor's noise scale.
    estimate_bias : bool
        Estimate and remove each sensor's misalignment (rotation and shift on the floor).
    scale_bounds : (float, float)
        Least and largest noise scale (on the covariance).
    max_bias_m : float
        Largest shift of the sensor's detections (where they were learned), metres.
    max_rotation_deg : float
        Largest rotation.
    align_memory : float
        Pairs remembered by the alignment (exponential forgetting).
    align_every : int
        New pairs between two alignment fits.
    window : int
        Gated distances kept per sensor for the noise scale.
    refit_every : int
        New samples between two noise-scale fits (at least a third of the window).
    refit_min_batches : int
        Batches of the sensor between two noise-scale fits, so a crowded room (a
        hundred samples in one batch) does not refit at every batch: a sensor's noise
        changes over seconds, not frames.
    min_samples : int
        Samples needed before the first fit.
    calibration_sigma : (float, float)
        Standard deviation of a sensor's calibration error before its alignment is
        learned: metres per axis, and degrees of yaw; ``(0, 0)`` trusts the calibration.
    twins : TwinAligner, optional
        Learns misalignments larger than a gate from the rigid map twin tracks agree on.
    """

    def __init__(
        self,
        *,
        adapt_noise: bool = True,
        estimate_bias: bool = True,
        scale_bounds: tuple[float, float] = (0.25, 25.0),
        max_bias_m: float = 0.5,
        max_rotation_deg: float = 5.0,
        align_memory: float = 2000.0,
        align_every: int = 30,
        window: int = 300,
        refit_every: int = 30,
        refit_min_batches: int = 10,
        min_samples: int = 60,
        calibration_sigma: tuple[float, float] = (0.0, 0.0),
        twins: TwinAligner | None = None,
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
        self.max_rotation = math.radians(max_rotation_deg)
        self.align_memory = align_memory
        self.align_every = align_every
        self.window = window
        self.refit_every = refit_every
        self.refit_min_batches = refit_min_batches
        self.min_samples = min_samples
        self.calibration_sigma = (calibration_sigma[0], math.radians(calibration_sigma[1]))
        self._sensors: dict[str, _SensorState] = {}
        self._coverage = Coverage()
        self.twins = twins

    # ------------------------------------------------------------------ state

    def snapshot(self) -> tuple[dict[str, _SensorState], Coverage, TwinAligner | None]:
        """The learned noise and alignment of every sensor, the coverage and the twins.

        The coverage is shared, not copied: each batch adds to it once, whatever the
        order, so a replay has nothing to undo.
        """
        states = {name: st.copy() for name, st in self._sensors.items()}
        return states, self._coverage, None if self.twins is None else self.twins.copy()

    def restore(self, state: tuple) -> None:  # type: ignore[type-arg]
        """Return to a snapshot (one taken before twins were kept has none)."""
        self._sensors = {name: st.copy() for name, st in state[0].items()}
        self._coverage = state[1]
        if len(state) > 2 and state[2] is not None and self.twins is not None:
            self.twins = state[2].copy()

    # ------------------------------------------------------------------ queries

    def noise_scale(self, sensor_id: str, distance: np.ndarray) -> np.ndarray:
        """Factor on the configured covariance of this sensor's detections at ``distance``."""
        st = self._sensors.get(sensor_id)
        if st is None:
            return np.ones(len(distance))
        return st.scale_at(np.asarray(distance, dtype=float))

    def cross_sensor_var(
        self, sensor_id: str, distance: np.ndarray, last_sensor: np.ndarray, names: list[str]
    ) -> np.ndarray | None:
        """Variance per axis added to this sensor's detections against other sensors' tracks.

        ``(n, m)``: detections at ``distance`` against tracks whose last detection came
        from another sensor (``last_sensor``, indices into ``names``) get both sensors'
        misalignment not yet learned; 0 against this sensor's own. ``None`` when
        calibrations are trusted (nothing is ever added).
        """
        if not self.estimate_bias or not any(self.calibration_sigma):
            return None
        out = np.zeros((len(last_sensor), len(distance)))
        own = self._unlearned(sensor_id, distance)
        for k in np.unique(last_sensor).tolist():
            other = names[k] if 0 <= k < len(names) else None
            if other != sensor_id:
                theirs = self._unlearned(other, distance)
                out[last_sensor == k] = own + theirs
        return out

    def _unlearned(self, sensor_id: str | None, distance: np.ndarray) -> np.ndarray:
        shift, yaw = self.calibration_sigma
        prior = shift**2 + (yaw * np.asarray(distance, dtype=float)) ** 2
        st = self._sensors.get(sensor_id) if sensor_id is not None else None
        pairs = 0.0 if st is None else st.align.fitted_weight
        return prior * ALIGNMENT_PAIR_VAR_M2 / (ALIGNMENT_PAIR_VAR_M2 + pairs * prior)

    def alignment(self, sensor_id: str) -> tuple[float, np.ndarray]:
        """A sensor's learned correction: rotation (radians) and translation (metres).

        A raw detection ``z`` is corrected to ``R(theta) z + shift``.
        """
        st = self._sensors.get(sensor_id)
        if st is None:
            return 0.0, np.zeros(2)
        return st.align.theta, st.align.shift.copy()

    def bias(self, sensor_id: str) -> np.ndarray:
        """Mean offset of a sensor's raw detections from the fused tracks (metres)."""
        st = self._sensors.get(sensor_id)
        if st is None or st.align.weight <= 0:
            return np.zeros(2)
        c = st.align.centroid()
        return c - st.align.apply(c[None])[0]

    def summary(self) -> dict[str, dict[str, float]]:
        """Per sensor: noise scale and alignment, for stats and logs."""
        out = {}
        for name, st in sorted(self._sensors.items()):
            bias = self.bias(name)
            out[name] = {
                "noise_scale": float(st.scale_at(np.array([4.0]))[0]),
                "rotation_deg": math.degrees(st.align.theta),
                "bias_x_m": float(bias[0]),
                "bias_y_m": float(bias[1]),
            }
        return out

    def correct(self, dets: DetectionArrays) -> DetectionArrays:
        """The detections with their sensor's misalignment removed; marks its coverage."""
        self._coverage.mark(dets.sensor_id, dets.seq, dets.xy, dets.distance)
        st = self._sensors.get(dets.sensor_id)
        if st is None or st.align.weight <= 0 or not len(dets):
            return dets
        return replace(dets, xy=st.align.apply(dets.xy))

    def clutter_density(self, sensor_id: str) -> float:
        """Detections per frame and square metre that no track explains, for a sensor."""
        st = self._sensors.get(sensor_id)
        if st is None or not self._coverage.known(sensor_id):
            return MIN_CLUTTER_DENSITY
        covered = self._coverage.covered_cells(sensor_id)
        area = max(covered, 1) * COVERAGE_CELL_M**2
        return max(st.unexplained_per_frame / area, MIN_CLUTTER_DENSITY)

    def observe_frame(self, sensor_id: str, unexplained: int) -> None:
        """A frame of this sensor left ``unexplained`` detections to no track."""
        st = self._sensors.setdefault(
            sensor_id, _SensorState(align=RigidAlignment(memory=self.align_memory))
        )
        st.unexplained_per_frame += CLUTTER_RATE * (unexplained - st.unexplained_per_frame)

    def covers(self, sensor_id: str, xy: np.ndarray) -> np.ndarray:
        """Mask of floor positions ``xy (n, 2)`` where this sensor has reported people."""
        return self._coverage.covers(sensor_id, xy)

    def hidden(
        self, sensor_id: str, xy: np.ndarray, seen: np.ndarray, twin_m: float
    ) -> np.ndarray:
        """Mask of floor positions ``xy (n, 2)`` hidden from this sensor behind ``xy[seen]``."""
        return self._coverage.hidden(sensor_id, xy, seen, twin_m)

    # ----------------------------------------------------------------- learning

    def learn(self, updates: SensorUpdates) -> None:
        """Learn from one batch's unambiguous updates of confirmed tracks."""
        u = updates
        if not len(u.detected):
            return
        st = self._sensors.setdefault(
            u.sensor_id, _SensorState(align=RigidAlignment(memory=self.align_memory))
        )
        if self.adapt_noise:
            innovation = u.detected - u.predicted
            cut = u.gate * (u.track_var + st.scale_at(u.distance) * u.model_var)
            q = np.einsum("ij,ij->i", innovation, innovation)
            rows = np.column_stack([q, u.track_var, u.model_var, cut, u.distance])
            self._add_samples(st, rows)
        multi_sensor = u.multi_sensor
        if self.twins is not None:
            others = [other for other in self._sensors if other != u.sensor_id]
            seen = self._coverage.covers_any(others, u.predicted)
            for multi in multi_sensor[seen].tolist():
                st.shared += SHARED_RATE * (multi - st.shared)
        if self.estimate_bias and multi_sensor.any():
            raw = st.align.invert(u.detected[multi_sensor])
            st.align.add(raw, u.predicted[multi_sensor])
            st.since_align += int(multi_sensor.sum())
            if st.since_align >= self.align_every:
                st.since_align = 0
                st.align.fit()
                self._bound(st.align)
                self._fix_gauge()

    def observe_tracks(self, table: TrackTable, t: float, names: list[str]) -> None:
        """Learn from the twin tracks of sensors whose misalignment no shared track shows."""
        twins = self.twins
        if twins is None or not self.estimate_bias or len(table) < 2 or not twins.due(t):
            return
        shares = [self._sensors[n].shared if n in self._sensors else 1.0 for n in names]
        unshared = {k for k, share in enumerate(shares) if share < UNSHARED_BELOW}
        for lesson in twins.observe(table, t, unshared):
            self._teach(names, lesson)

    def _teach(self, names: list[str], lesson: TwinLesson) -> None:
        """Move the alignments so that the twins meet half-way."""
        middle = 0.5 * (lesson.a + lesson.b)
        moves = [(k, lesson.a) for k in lesson.sensors_a] + [(lesson.sensor_b, lesson.b)]
        for k, seen in moves:
            if k >= min(len(names), SENSOR_SLOTS - 1):  # the last slot is shared
                continue
            st = self._sensors.get(names[k])
            if st is None:
                continue
            if st.align.weight < len(seen):
                st.align.add(st.align.invert(seen), middle)
                st.align.fit()
            else:
                st.align.then(*rigid_fit(seen, middle))
            self._bound(st.align)
        self._fix_gauge()

    def _add_samples(self, st: _SensorState, rows: np.ndarray) -> None:
        if len(st.samples) < self.window:
            st.samples = np.concatenate([st.samples, rows])[-self.window :]
        else:
            idx = (st.head + np.arange(len(rows))) % self.window
            st.samples[idx] = rows
            st.head = int((st.head + len(rows)) % self.window)
        st.since_fit += len(rows)
        st.batches_since_fit += 1
        due = max(self.refit_every, len(st.samples) // 3)
        if (
            len(st.samples) >= self.min_samples
            and st.since_fit >= due
            and st.batches_since_fit >= self.refit_min_batches
        ):
            st.since_fit = st.batches_since_fit = 0
            st.scales = self._fit_bands(st.samples)

    def _fit_bands(self, samples: np.ndarray) -> np.ndarray:
        """A scale per distance band; bands with too few samples take the overall one."""
        overall = gated_noise_scale(samples, self.scale_bounds)
        band = np.digitize(samples[:, 4], NOISE_BANDS_M) - 1
        scales = np.full(len(NOISE_BAND_CENTRES_M), overall)
        for b in range(len(scales)):
            rows = samples[band == b]
            if len(rows) >= self.min_samples // 2:
                scales[b] = gated_noise_scale(rows, self.scale_bounds)
        return scales

    def _bound(self, align: RigidAlignment) -> None:
        """Keep a correction within the largest rotation and shift believed possible."""
        if abs(align.theta) > self.max_rotation:
            align.theta = math.copysign(self.max_rotation, align.theta)
            zbar, xbar = align.sum_z / align.weight, align.sum_x / align.weight
            align.shift = xbar - rotation(align.theta) @ zbar
        c = align.centroid()
        moved = align.apply(c[None])[0] - c
        norm = float(np.hypot(*moved))
        if norm > self.max_bias_m:
            align.shift = align.shift - moved * (1.0 - self.max_bias_m / norm)

    def _fix_gauge(self) -> None:
        """Make the sensors' mean correction the identity (the world is their consensus).

        Moving every sensor at once changes no association, so nothing in the data fixes
        it. Each correction ``T`` becomes ``G o T``, ``G`` the rigid move bringing the
        weighted mean rotation and displacement to zero, each sensor's displacement taken
        at its own pairs' centroid, the only place it is measured: at one common point a
        sensor's small rotation is carried metres from its data across a large room
        (``tests/tracking/test_sensor_model.py``: the world 0.06-0.5 m off in a hall).
        """
        learned = [st.align for st in self._sensors.values() if st.align.weight > 0]
        if len(learned) < 2:
            return
        w = np.array([a.weight for a in learned])
        own = np.array([a.centroid() for a in learned])
        c = np.average(own, axis=0, weights=w)
        mean_theta = float(np.average([a.theta for a in learned], weights=w))
        back = rotation(-mean_theta)
        there = np.array([a.apply(o[None])[0] for a, o in zip(learned, own, strict=True)])
        mean_moved = np.average((there - c) @ back.T - (own - c), axis=0, weights=w)
        for a in learned:
            a.theta -= mean_theta
            a.shift = back @ (a.shift - c) + c - mean_moved
