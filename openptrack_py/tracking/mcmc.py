"""The childcare paper's tracker, for comparison: per-person MCMC particle groups.

Zhang et al. ("Children Behavior Tracking and Personal Identification By Multiple Kinect
Sensors", §2.3) track each child with a group of particles of its own, never shared
with another child, and find each frame's maximum-a-posteriori configuration with a
Markov chain Monte Carlo particle filter:

* **motion model** (Eq. 3): variable acceleration, ``X = X_prev + X' dt``,
  ``X' = X'_prev + X'' dt``, ``X'' = X''_prev + mu`` with Gaussian ``mu``;
* **observation likelihood** (Eq. 4): ``P(Z|X) ∝ exp(sum_j w_j P_j(Z|X))`` over a motion
  detector (Eq. 7, the distance ``D`` from the hypothesis to the nearest detected area:
  ``-beta D^2`` here, the paper's ``beta`` being negative), a colour detector (Eq. 8,
  the correlation of hue histograms with the person's model) and a face detector (Eq.
  5-6, an identity embedding's similarity above a threshold, weighted by the embedding's
  confidence as the paper weights faces by angle and distance); weights ``w_motion =
  gamma w_colour`` and ``w_motion + w_colour + w_face = 1`` (Eq. 9);
* **MCMC**: for every group, a Metropolis-Hastings chain whose proposals are the
  group's previous particles moved by the motion model, accepted by the likelihood
  ratio (it samples ``P(Z|X)`` times the prediction), ``burn_in`` steps dropped,
  ``particles`` kept; the groups' chains run side by side (one array step for all);
* **estimate** (§2.3.3, point 2): the centre of the detected area closest to the
  particles' mean, if one is within ``snap_m``; several people may share one area
  (point 3).

The paper tracks a registered class; here people come and go, so (our addition) a
detection that no group explains starts a candidate, confirmed after ``confirm_hits``
sightings within ``confirm_s``; a group no detection has been near for ``forget_s`` is
dropped. With several sensors each step sees every sensor's latest batch of the last
:data:`FRAME_S` (the paper filters whole frames). It stands in for
:class:`~openptrack_py.tracking.tracker.Tracker` (``step(batch) -> TrackBatch``) in
:class:`~openptrack_py.tracking.TrackingPipeline` and ``openptrack eval --tracker mcmc``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from openptrack_py.messages.detection import DetectionBatch
from openptrack_py.messages.track import Track, TrackBatch

__all__ = ["McmcParams", "McmcTracker"]

ACCEL_MEMORY_S = 0.5
"""Our addition to Eq. 3: an acceleration fades over about this long (the paper's random
walk in acceleration lets a person's velocity run away between sightings)."""
FRAME_S = 0.04
"""The paper filters whole frames: each step sees every sensor's batch of the last
``FRAME_S`` (one frame period of 30 Hz sensors, give or take their phases)."""
PROPOSAL_SPREAD = np.array([0.05, 0.05, 0.15, 0.15, 0.3, 0.3])
"""Standard deviation of the spread added to each proposal (x, y m; vx, vy m/s; ax, ay m/s^2)."""
AREA_M = 0.4
"""Detections of several sensors this close are one detected area."""
COPY_M = 0.3
"""Two groups closer than this (a body's radius) are on one person."""
MAX_SPEED_MPS = 3.0
"""Our addition: nobody in a room runs faster."""


@dataclass(frozen=True)
class McmcParams:
    """Settings of :class:`McmcTracker` (the paper gives no values; these are ours).

    Parameters
    ----------
    particles : int
        Samples kept per group.
    burn_in : int
        Chain steps dropped first.
    thin : int
        Chain steps per kept sample.
    accel_sigma_mps2 : float
        Standard deviation of the acceleration noise ``mu`` per second.
    beta : float
        Motion likelihood: ``-beta D^2`` (``D`` in metres).
    gamma : float
        ``w_motion = gamma w_colour``.
    face_threshold : float
        Embedding similarity below which the face detector says nothing (Eq. 5).
    snap_m : float
        Largest distance from the particles' mean to the detected area it snaps to.
    gate_m : float
        A detection farther than this from every group is unexplained.
    confirm_hits, confirm_s : int, float
        A candidate becomes a person after this many sightings within this long.
    forget_s : float
        A group with no detection near it this long is dropped.
    share_max_s : float
        A group within :data:`COPY_M` of an older one this long is dropped (ours: with no
        registered class, two groups on one person would otherwise never part).
    seed : int
        Seed of the sampler.
    """

    particles: int = 40
    burn_in: int = 20
    thin: int = 2
    accel_sigma_mps2: float = 3.0
    beta: float = 25.0
    gamma: float = 3.0
    face_threshold: float = 0.5
    snap_m: float = 0.6
    gate_m: float = 0.8
    confirm_hits: int = 8
    confirm_s: float = 0.5
    forget_s: float = 2.0
    share_max_s: float = 2.0
    seed: int = 0


@dataclass
class _Group:
    """One person's particles (``(n, 6)``: x y vx vy ax ay) and looks."""

    id: int
    particles: np.ndarray
    first_t: float
    seen_t: float
    shared_since: float | None = None
    colour: np.ndarray | None = None
    colour_n: int = 0
    face: np.ndarray | None = None
    estimate: np.ndarray = field(default_factory=lambda: np.zeros(2))


def _areas(
    dets: list,
) -> tuple[np.ndarray, list[np.ndarray | None], list[tuple[np.ndarray, float] | None]]:
    """The frame's detected areas, each with its look and face.

    Detections of every sensor within :data:`AREA_M` of one another are one area (the
    paper detects areas on one ground plane of every sensor's points): its centre the
    mean, its look the mean look, its face the most confident.
    """
    xy = np.array([(d.x, d.y) for d in dets], dtype=float).reshape(-1, 2)
    label = np.full(len(dets), -1)
    areas = 0
    for k in range(len(dets)):
        if label[k] >= 0:
            continue
        near = (np.hypot(*(xy - xy[k]).T) <= AREA_M) & (label < 0)
        label[near] = areas
        areas += 1
    centres = np.array([xy[label == a].mean(axis=0) for a in range(areas)]).reshape(-1, 2)
    looks: list[np.ndarray | None] = []
    faces: list[tuple[np.ndarray, float] | None] = []
    for a in range(areas):
        members = [dets[k] for k in np.flatnonzero(label == a)]
        seen = [np.asarray(d.appearance, float) for d in members if d.appearance is not None]
        same = seen and all(v.shape == seen[0].shape for v in seen)
        looks.append(np.mean(seen, axis=0) if same else None)
        with_face = [d for d in members if d.face is not None]
        best = max(with_face, key=lambda d: d.face_confidence or 0.0, default=None)
        faces.append(
            None if best is None else (np.asarray(best.face, float), best.face_confidence or 1.0)
        )
    return centres, looks, faces


def _correlation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pearson correlation of histogram ``a`` with each row of ``b`` (the paper's Eq. 8)."""
    a = a - a.mean()
    b = b - b.mean(axis=1, keepdims=True)
    denom = np.sqrt((a * a).sum() * (b * b).sum(axis=1)) + 1e-12
    return (b @ a) / denom


class McmcTracker:
    """Per-person MCMC particle groups (see the module).

    Parameters
    ----------
    params : McmcParams, optional
        Settings.
    """

    def __init__(self, params: McmcParams | None = None) -> None:
        self.params = params or McmcParams()
        self.rng = np.random.default_rng(self.params.seed)
        self.groups: list[_Group] = []
        self.candidates: list[tuple[float, float, float]] = []  # t, x, y
        self.time: float | None = None
        self.max_id = 0
        self.seq = 0
        self.frame_id = "world"
        self.counters = {"steps": 0, "late_applied": 0, "late_dropped": 0}
        self._latest: dict[str, DetectionBatch] = {}

    # ------------------------------------------------------------------ one batch

    def step(self, batch: DetectionBatch) -> TrackBatch:
        """Apply one detection batch; return the tracks after it."""
        self.counters["steps"] += 1
        if self.time is not None and batch.stamp < self.time:
            self.counters["late_dropped"] += 1  # the paper's filter runs frame by frame
            return self._output(self.time)
        dt = 0.0 if self.time is None else batch.stamp - self.time
        self.time = t = batch.stamp
        # one frame of the whole room: every sensor's latest batch of the last moment
        self._latest[batch.sensor_id] = batch
        dets = [d for b in self._latest.values() if t - b.stamp <= FRAME_S for d in b.detections]
        xy, looks, faces = _areas(dets)
        used = np.zeros(len(xy), dtype=bool)
        if self.groups:
            used = self._track_all(dt, xy, looks, faces, t)
        self._births(xy, used, looks, t)
        self.groups = [g for g in self.groups if t - g.seen_t <= self.params.forget_s]
        return self._output(t)

    def _track_all(
        self,
        dt: float,
        xy: np.ndarray,
        looks: list[np.ndarray | None],
        faces: list[tuple[np.ndarray, float] | None],
        t: float,
    ) -> np.ndarray:
        """Move every group to ``t`` (MCMC where a detection is near); detections taken."""
        p = self.params
        priors = np.stack([self._predict(g.particles, dt) for g in self.groups])  # (G, N, 6)
        means = priors.mean(axis=1)
        took = np.zeros(len(xy), dtype=bool)
        if len(xy):
            d2 = ((means[:, None, :2] - xy[None]) ** 2).sum(axis=2)
            observed = d2.min(axis=1) <= p.gate_m**2
        else:
            observed = np.zeros(len(self.groups), dtype=bool)
        for g, prior in zip(self.groups, priors, strict=True):
            g.particles, g.estimate = prior, prior[:, :2].mean(axis=0)
        rows = np.flatnonzero(observed)
        if not len(rows):
            return took
        terms = [self._detector_terms(self.groups[r], looks, faces) for r in rows]
        samples = self._chains(priors[rows], xy, terms)
        for r, group_samples in zip(rows.tolist(), samples, strict=True):
            group = self.groups[r]
            group.particles = group_samples
            mean = group_samples[:, :2].mean(axis=0)
            dist = np.hypot(*(xy - mean).T)
            nearest = int(np.argmin(dist))
            group.estimate = mean
            if dist[nearest] <= p.snap_m:
                group.estimate = xy[nearest].copy()  # the area's centre (§2.3.3, point 2)
                group.seen_t = t
                took[nearest] = True  # others may share it too (point 3)
                self._learn(group, looks[nearest], faces[nearest])
        self._drop_copies(t)
        return took

    def _drop_copies(self, t: float) -> None:
        """Drop a group that has stayed on top of an older one for ``share_max_s`` (ours)."""
        p = self.params
        if len(self.groups) < 2:
            return
        xy = np.array([g.estimate for g in self.groups])
        close = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1)) < COPY_M
        np.fill_diagonal(close, False)
        for i, group in enumerate(self.groups):
            older = [
                j for j in np.flatnonzero(close[i]).tolist()
                if self.groups[j].first_t < group.first_t
            ]  # fmt: skip
            if not older:
                group.shared_since = None
                continue
            group.shared_since = group.shared_since or t
            if t - group.shared_since > p.share_max_s:
                group.seen_t = -math.inf  # a copy of someone else's track: dropped

    def _predict(self, particles: np.ndarray, dt: float) -> np.ndarray:
        """The motion model (Eq. 3), acceleration pulled back to 0 and speed capped (ours)."""
        out = particles.copy()
        if dt <= 0:
            return out
        p = self.params
        noise = self.rng.normal(0.0, p.accel_sigma_mps2 * math.sqrt(dt), (len(out), 2))
        out[:, 4:6] = out[:, 4:6] * math.exp(-dt / ACCEL_MEMORY_S) + noise
        out[:, 2:4] += out[:, 4:6] * dt
        speed = np.hypot(out[:, 2], out[:, 3])
        out[:, 2:4] *= np.minimum(1.0, MAX_SPEED_MPS / np.maximum(speed, 1e-9))[:, None]
        out[:, 0:2] += out[:, 2:4] * dt
        return out

    def _detector_terms(
        self,
        group: _Group,
        looks: list[np.ndarray | None],
        faces: list[tuple[np.ndarray, float] | None],
    ) -> tuple[np.ndarray, np.ndarray]:
        """Per detection: ``w_motion, w_colour P_colour + w_face P_face`` (Eq. 4-9)."""
        p = self.params
        n = len(looks)
        colour = np.zeros(n)
        if group.colour is not None:
            for k, look in enumerate(looks):
                if look is not None and look.shape == group.colour.shape:
                    colour[k] = _correlation(group.colour, look[None, :])[0]
        face, w_face = np.zeros(n), np.zeros(n)
        if group.face is not None:
            for k, item in enumerate(faces):
                if item is not None and item[0].shape == group.face.shape:
                    sim = float(item[0] @ group.face / (np.linalg.norm(item[0]) + 1e-12))
                    if sim > p.face_threshold:
                        face[k] = (sim - p.face_threshold) / (1.0 - p.face_threshold)
                        w_face[k] = min(max(item[1], 0.0), 1.0)
        w_colour = (1.0 - w_face) / (1.0 + p.gamma)
        w_motion = p.gamma * w_colour
        return w_motion, w_colour * colour + w_face * face

    def _chains(
        self, priors: np.ndarray, xy: np.ndarray, terms: list[tuple[np.ndarray, np.ndarray]]
    ) -> np.ndarray:
        """Metropolis-Hastings for every observed group at once; ``(G, particles, 6)``.

        Each proposal is one of the group's predicted particles (a previous sample moved by
        the motion model, so its position and velocity stay consistent) spread a little
        (:data:`PROPOSAL_SPREAD`, so that the samples do not collapse onto one), accepted
        by the ratio of likelihoods: the chain samples ``P(Z|X)`` times the prediction.
        """
        p = self.params
        n_groups, n = priors.shape[0], priors.shape[1]
        w_motion = np.stack([tm[0] for tm in terms])  # (G, K)
        appearance = np.stack([tm[1] for tm in terms])
        rows = np.arange(n_groups)

        def log_like(state: np.ndarray) -> np.ndarray:
            d2 = ((state[:, None, :2] - xy[None]) ** 2).sum(axis=2)  # (G, K)
            k = np.argmin(d2, axis=1)
            return w_motion[rows, k] * (-p.beta * d2[rows, k]) + appearance[rows, k]

        steps = p.burn_in + p.particles * p.thin
        picks = self.rng.integers(0, n, (steps + 1, n_groups))
        jitter = self.rng.normal(0.0, 1.0, (steps + 1, n_groups, 6)) * PROPOSAL_SPREAD
        state = priors[rows, picks[0]] + jitter[0]
        current = log_like(state)
        kept = []
        for s in range(steps):
            proposal = priors[rows, picks[s + 1]] + jitter[s + 1]
            value = log_like(proposal)
            accept = np.log(self.rng.random(n_groups)) < value - current
            state[accept], current[accept] = proposal[accept], value[accept]
            if s >= p.burn_in and (s - p.burn_in) % p.thin == 0:
                kept.append(state.copy())
        return np.stack(kept, axis=1)

    def _learn(
        self, group: _Group, look: np.ndarray | None, face: tuple[np.ndarray, float] | None
    ) -> None:
        if look is not None and look.sum() > 0:
            look = look / look.sum()
            if group.colour is None or group.colour.shape != look.shape:
                group.colour, group.colour_n = look, 1
            else:
                group.colour_n += 1
                rate = max(1.0 / group.colour_n, 0.02)
                group.colour = (1 - rate) * group.colour + rate * look
        if face is not None:
            unit = face[0] / (np.linalg.norm(face[0]) + 1e-12)
            group.face = unit if group.face is None else group.face + 0.1 * (unit - group.face)

    def _births(
        self, xy: np.ndarray, used: np.ndarray, looks: list[np.ndarray | None], t: float
    ) -> None:
        """Unexplained detections: candidates, and new groups when seen often enough."""
        p = self.params
        self.candidates = [c for c in self.candidates if t - c[0] <= p.confirm_s]
        estimates = np.array([g.estimate for g in self.groups]).reshape(-1, 2)
        for k in np.flatnonzero(~used):
            if len(estimates) and np.hypot(*(estimates - xy[k]).T).min() <= p.gate_m:
                continue  # near a person: theirs, or a piece of them
            near = [
                c for c in self.candidates if math.hypot(c[1] - xy[k, 0], c[2] - xy[k, 1]) < 0.5
            ]
            if len(near) + 1 >= p.confirm_hits:
                self._start(xy[k], looks[k], t)
                self.candidates = [c for c in self.candidates if c not in near]
                estimates = np.array([g.estimate for g in self.groups]).reshape(-1, 2)
            else:
                self.candidates.append((t, float(xy[k, 0]), float(xy[k, 1])))

    def _start(self, xy: np.ndarray, look: np.ndarray | None, t: float) -> None:
        self.max_id += 1
        particles = np.zeros((self.params.particles, 6))
        particles[:, 0:2] = xy + self.rng.normal(0, 0.1, (self.params.particles, 2))
        group = _Group(self.max_id, particles, t, t, estimate=np.array(xy, dtype=float))
        self._learn(group, look, None)
        self.groups.append(group)

    def _output(self, t: float) -> TrackBatch:
        self.seq += 1
        tracks = []
        for g in self.groups:
            v = g.particles[:, 2:4].mean(axis=0)
            tracks.append(
                Track(id=g.id, x=float(g.estimate[0]), y=float(g.estimate[1]), z=0.9,
                      height=1.7, vx=float(v[0]), vy=float(v[1]), age=t - g.first_t,
                      confidence=1.0, visibility=int(t - g.seen_t < 0.5))
            )  # fmt: skip
        ids = tuple(tr.id for tr in tracks)
        return TrackBatch(t, self.seq, self.frame_id, tuple(tracks), ids, self.max_id)
