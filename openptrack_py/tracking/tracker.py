"""The multi-person tracker: one ``step`` per detection batch.

Each batch is one step (DESIGN §4):

1. every track is predicted to the batch's capture time with the real ``dt``;
2. each detection is compared with each track by the squared Mahalanobis distance of
   its residual under that track's *predicted* innovation covariance, so the gate
   widens while a person is unseen;
3. pairs outside the chi-square gate are inadmissible;
4. a global nearest-neighbour assignment picks pairs (cost = negative log-likelihood +
   the detector confidence term + any extra cost terms, e.g. appearance), first among
   confirmed tracks, then among tentative tracks for the detections left;
5. assigned tracks are updated; unexplained confident detections start tentative tracks;
   tentative tracks are confirmed after enough detections; stale tracks are deleted.

A batch captured before the tracker's current time (it arrived late) is applied exactly:
the tracker keeps a snapshot of its state before each of the steps of the last
``max_lateness_s``, returns to the last one taken before the late capture, and replays
the late batch and every later one in capture order (``late_policy: replay``). A batch
later than the history reaches is dropped and counted (``late_policy: drop`` drops every
late batch).
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from openptrack_py.config import TrackerConfig
from openptrack_py.messages.detection import DetectionBatch
from openptrack_py.messages.track import Track, TrackBatch, Visibility
from openptrack_py.tracking.association import GlobalNearestNeighbour
from openptrack_py.tracking.gating import ChiSquareGater
from openptrack_py.tracking.lifecycle import ConfidenceInitiator, TimeDeleter
from openptrack_py.tracking.measurement import PositionMeasurement, PositionVelocityMeasurement
from openptrack_py.tracking.motion import ConstantVelocity
from openptrack_py.tracking.ukf import MerweSigmaPoints, Projection, UnscentedKalmanFilter

log = logging.getLogger(__name__)

_HISTORY = 48  # positions kept per track for the velocity measurement
_HISTORY_SPACING_S = 0.04


class CostTerm(Protocol):
    """An extra association cost (e.g. appearance dissimilarity).

    Called with the tracker and the batch's kept detections; returns an ``(N, M)``
    array added to the cost of admissible pairs.
    """

    def cost(self, tracker: Tracker, detections: DetectionArrays) -> np.ndarray:
        """Extra cost of each track-detection pair."""


def mahalanobis(
    resid: np.ndarray, pzz: np.ndarray, noise: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Squared Mahalanobis distances and log-determinants of a stack of residuals.

    ``resid (..., m)`` under the covariances ``S = pzz + noise`` (both broadcastable to
    ``(..., m, m)``). The 2-D case (floor position) uses the closed-form inverse of the
    three distinct entries of ``S``, without forming ``S``: exact, and several times
    faster than a batched solve.
    """
    if resid.shape[-1] == 2:
        a = pzz[..., 0, 0] + noise[..., 0, 0]
        b = pzz[..., 0, 1] + noise[..., 0, 1]
        c = pzz[..., 1, 1] + noise[..., 1, 1]
        det = a * c - b * b
        r0, r1 = resid[..., 0], resid[..., 1]
        return (c * r0 * r0 - 2.0 * b * r0 * r1 + a * r1 * r1) / det, np.log(det)
    s = pzz + noise
    d2 = np.einsum("...i,...i->...", resid, np.linalg.solve(s, resid[..., None])[..., 0])
    return d2, np.linalg.slogdet(s)[1]


@dataclass(frozen=True)
class DetectionArrays:
    """The detections of one batch that the tracker uses, as arrays.

    Parameters
    ----------
    index : ndarray
        Position of each kept detection in the batch.
    xy, z, height, confidence, distance : ndarray
        Per-detection values.
    """

    index: np.ndarray
    xy: np.ndarray
    z: np.ndarray
    height: np.ndarray
    confidence: np.ndarray
    distance: np.ndarray

    def __len__(self) -> int:
        return len(self.index)

    @classmethod
    def from_batch(cls, batch: DetectionBatch, min_confidence: float) -> DetectionArrays:
        """Arrays of the batch's detections at least ``min_confidence`` confident."""
        kept = [(i, d) for i, d in enumerate(batch.detections) if d.confidence >= min_confidence]
        if not kept:
            empty = np.zeros(0)
            return cls(np.zeros(0, dtype=int), np.zeros((0, 2)), empty, empty, empty, empty)
        rows = np.array([(d.x, d.y, d.z, d.height, d.confidence, d.distance) for _, d in kept])
        return cls(
            index=np.array([i for i, _ in kept]),
            xy=rows[:, 0:2],
            z=rows[:, 2],
            height=rows[:, 3],
            confidence=rows[:, 4],
            distance=rows[:, 5],
        )


@dataclass
class TrackTable:
    """Every track's state, as parallel arrays (one row per track)."""

    ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    x: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    cov: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    z: np.ndarray = field(default_factory=lambda: np.zeros(0))
    height: np.ndarray = field(default_factory=lambda: np.zeros(0))
    confidence: np.ndarray = field(default_factory=lambda: np.zeros(0))
    first_seen: np.ndarray = field(default_factory=lambda: np.zeros(0))
    last_seen: np.ndarray = field(default_factory=lambda: np.zeros(0))
    hits: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    confirmed: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    hist_t: np.ndarray = field(default_factory=lambda: np.zeros((0, _HISTORY)))
    hist_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, _HISTORY, 2)))

    COLUMNS = (
        "ids", "x", "cov", "z", "height", "confidence", "first_seen", "last_seen", "hits",
        "confirmed", "hist_t", "hist_xy",
    )  # fmt: skip

    def __len__(self) -> int:
        return len(self.ids)

    def keep(self, mask: np.ndarray) -> None:
        """Drop the rows where ``mask`` is False."""
        for name in self.COLUMNS:
            setattr(self, name, getattr(self, name)[mask])

    def copy(self) -> TrackTable:
        """An independent copy."""
        return TrackTable(**{name: getattr(self, name).copy() for name in self.COLUMNS})

    def append(self, **rows: np.ndarray) -> None:
        """Add rows (one array per column, same length)."""
        for name in self.COLUMNS:
            setattr(self, name, np.concatenate([getattr(self, name), rows[name]]))


@dataclass(frozen=True)
class _Snapshot:
    table: TrackTable
    time: float | None
    max_id: int
    started: int
    deleted: int


class Tracker:
    """Tracks people on the ground plane from detection batches of any number of sensors.

    Parameters
    ----------
    motion : ConstantVelocity
        Motion model.
    measurement : PositionMeasurement or PositionVelocityMeasurement
        Measurement model.
    gater : ChiSquareGater
        Gate; its ``dof`` must equal the measurement dimension.
    associator : GlobalNearestNeighbour
        Associator.
    initiator : ConfidenceInitiator
        Starts and confirms tracks.
    deleter : TimeDeleter
        Deletes stale tracks.
    detector_weight : float
        Weight of detection confidence in the association cost.
    min_confidence_detections : float
        Detections below this confidence are ignored.
    visibility_timeout_s : float
        Tracks unseen for longer are reported ``NOT_VISIBLE``.
    initial_velocity_sigma_mps : float
        Velocity uncertainty of a new track.
    height_smoothing : float
        Weight of a new height in the height's moving average.
    publish_tentative : bool
        Include tentative tracks in the output.
    publish_unseen_s : float
        Leave out of the output tracks unseen for longer (they stay alive).
    late_policy : {"replay", "drop"}
        Out-of-sequence batches: replay from the last snapshot before them, or drop.
    max_lateness_s : float
        How far back snapshots reach; later batches are dropped.
    max_replay_steps : int
        A late batch that would replay more steps than this is dropped.
    max_tracks : int
        No new track starts while this many exist.
    cost_terms : sequence of CostTerm
        Extra association costs.

    Examples
    --------
    >>> from openptrack_py.tracking import build_tracker
    >>> tracker = build_tracker()
    >>> out = tracker.step(batch)  # doctest: +SKIP
    """

    def __init__(
        self,
        motion: ConstantVelocity,
        measurement: PositionMeasurement | PositionVelocityMeasurement,
        gater: ChiSquareGater,
        associator: GlobalNearestNeighbour,
        initiator: ConfidenceInitiator,
        deleter: TimeDeleter,
        *,
        detector_weight: float = -1.0,
        min_confidence_detections: float = 0.0,
        visibility_timeout_s: float = 0.25,
        initial_velocity_sigma_mps: float = 1.5,
        height_smoothing: float = 0.1,
        publish_tentative: bool = False,
        publish_unseen_s: float = 0.5,
        late_policy: str = "replay",
        max_lateness_s: float = 1.0,
        max_replay_steps: int = 64,
        max_tracks: int = 1000,
        cost_terms: Sequence[CostTerm] = (),
    ) -> None:
        if gater.dof != measurement.dim:
            raise ValueError(
                f"Tracker: gater.dof ({gater.dof}) must equal the measurement dimension "
                f"({measurement.dim})"
            )
        if late_policy not in ("replay", "drop"):
            raise ValueError(
                f"Tracker: late_policy must be 'replay' or 'drop', got {late_policy!r}"
            )
        self.motion = motion
        self.measurement = measurement
        self.gater = gater
        self.associator = associator
        self.initiator = initiator
        self.deleter = deleter
        self.detector_weight = detector_weight
        self.min_confidence_detections = min_confidence_detections
        self.visibility_timeout_s = visibility_timeout_s
        self.initial_velocity_sigma_mps = initial_velocity_sigma_mps
        self.height_smoothing = height_smoothing
        self.publish_tentative = publish_tentative
        self.publish_unseen_s = publish_unseen_s
        self.late_policy = late_policy
        self.max_lateness_s = max_lateness_s
        self.max_replay_steps = max_replay_steps
        # (stamp, state before the step, batch) of recent in-order steps
        self._history: deque[tuple[float, _Snapshot, DetectionBatch]] = deque()
        self.max_tracks = max_tracks
        self.cost_terms = list(cost_terms)
        self.ukf = UnscentedKalmanFilter(MerweSigmaPoints(4))
        self.table = TrackTable()
        self.time: float | None = None
        self.max_id = 0
        self.seq = 0
        self.frame_id = "world"
        self.counters: dict[str, int] = dict.fromkeys(
            (
                "steps",
                "late_applied",
                "late_dropped",
                "replayed_steps",
                "tracks_started",
                "tracks_deleted",
            ),
            0,
        )

    # ------------------------------------------------------------------- public

    def step(self, batch: DetectionBatch) -> TrackBatch:
        """Apply one detection batch; return the tracks after it."""
        self.counters["steps"] += 1
        if self.time is not None and batch.stamp < self.time:
            self._apply_late(batch)
            return self.output(self.time)
        self._advance(batch)
        return self.output(batch.stamp)

    def _advance(self, batch: DetectionBatch) -> None:
        """One in-order step, remembered for replays."""
        t = batch.stamp
        if self.late_policy == "replay" and self.max_lateness_s > 0:
            self._history.append((t, self._snapshot(), batch))
            while self._history and self._history[0][0] < t - self.max_lateness_s:
                self._history.popleft()
        dets = DetectionArrays.from_batch(batch, self.min_confidence_detections)
        self._predict_to(t)
        assigned, in_gate = self._associate_and_update(dets, t)
        self._start_tracks(dets, assigned, in_gate, t)
        self._lifecycle(t)

    def _snapshot(self) -> _Snapshot:
        c = self.counters
        return _Snapshot(
            self.table.copy(), self.time, self.max_id, c["tracks_started"], c["tracks_deleted"]
        )

    def _apply_late(self, batch: DetectionBatch) -> None:
        """Replay from the last state before ``batch``'s capture, or drop it."""
        assert self.time is not None
        history = self._history
        later = [i for i, (stamp, _, _) in enumerate(history) if stamp > batch.stamp]
        first = later[0] if later else len(history)
        usable = (
            self.late_policy == "replay"
            and self.time - batch.stamp <= self.max_lateness_s
            and first < len(history)
            and (history[first][1].time is None or history[first][1].time <= batch.stamp)
            and len(history) - first <= self.max_replay_steps
        )
        if not usable:
            self.counters["late_dropped"] += 1
            return
        self.counters["late_applied"] += 1
        replay = [entry[2] for entry in list(history)[first:]]
        snapshot = history[first][1]
        for _ in range(len(history) - first):
            history.pop()
        self.table, self.time, self.max_id = snapshot.table, snapshot.time, snapshot.max_id
        # what happened after the snapshot is undone, and will be counted again on replay
        self.counters["tracks_started"] = snapshot.started
        self.counters["tracks_deleted"] = snapshot.deleted
        self.counters["replayed_steps"] += len(replay)
        for queued in sorted([batch, *replay], key=lambda b: b.stamp):
            self._advance(queued)

    def adopt_state(self, other: Tracker) -> None:
        """Take over ``other``'s tracks, clock and id counter (after a reconfiguration)."""
        self.table = other.table
        self.time = other.time
        self.max_id = other.max_id
        self.seq = other.seq
        self.frame_id = other.frame_id
        self.counters = other.counters

    def output(self, t: float) -> TrackBatch:
        """The tracks as a message (confirmed ones unless ``publish_tentative``)."""
        tb = self.table
        self.seq += 1
        unseen = t - tb.last_seen
        shown = unseen <= self.publish_unseen_s
        if not self.publish_tentative:
            shown &= tb.confirmed
        rows = np.flatnonzero(shown)
        fresh = np.clip(1.0 - unseen[rows] / self.deleter.sec_before_old, 0.0, 1.0)
        columns = zip(
            tb.ids[rows].tolist(),
            tb.x[rows].tolist(),
            tb.z[rows].tolist(),
            tb.height[rows].tolist(),
            np.maximum(t - tb.first_seen[rows], 0.0).tolist(),
            np.clip(tb.confidence[rows] * fresh, 0.0, 1.0).tolist(),
            (unseen[rows] <= self.visibility_timeout_s).tolist(),
            tb.confirmed[rows].tolist(),
            strict=True,
        )
        tracks = [
            Track(
                id=ident,
                x=x[0],
                y=x[1],
                z=z,
                height=height,
                vx=x[2],
                vy=x[3],
                age=age,
                confidence=conf,
                visibility=Visibility.VISIBLE if visible else Visibility.NOT_VISIBLE,
                confirmed=confirmed,
            )
            for ident, x, z, height, age, conf, visible, confirmed in columns
        ]
        return TrackBatch(
            stamp=t,
            seq=self.seq,
            frame_id=self.frame_id,
            tracks=tuple(tracks),
            alive_ids=tuple(tb.ids.tolist()),
            max_id=self.max_id,
        )

    # --------------------------------------------------------------- internals

    def _predict_to(self, t: float) -> None:
        tb = self.table
        if self.time is not None and len(tb) and t > self.time:
            dt = np.full(len(tb), t - self.time)
            tb.x, tb.cov = self.ukf.predict(
                tb.x, tb.cov, dt, self.motion.fx, self.motion.noise(dt)
            )
        self.time = t if self.time is None else max(self.time, t)

    def _velocity_terms(self, dets: DetectionArrays, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Per-pair 4-D measurements and their noise (velocity from the track's past)."""
        tb = self.table
        assert isinstance(self.measurement, PositionVelocityMeasurement)
        m = self.measurement
        horizon = np.minimum(m.horizon_s, t - tb.first_seen)
        usable = horizon >= m.min_horizon_s
        past = np.array(
            [self._past_position(i, t - max(h, m.min_horizon_s)) for i, h in enumerate(horizon)]
        ).reshape(-1, 2)
        tau = np.maximum(horizon, m.min_horizon_s)
        vel = (dets.xy[None, :, :] - past[:, None, :]) / tau[:, None, None]
        z = np.concatenate([np.broadcast_to(dets.xy, vel.shape), vel], axis=2)
        return z, m.noise(dets.distance, usable)

    def _past_position(self, row: int, when: float) -> np.ndarray:
        tb = self.table
        times, xy = tb.hist_t[row], tb.hist_xy[row]
        valid = times > -np.inf
        if not valid.any():
            return tb.x[row, 0:2]
        order = np.argsort(times[valid])
        ts, ps = times[valid][order], xy[valid][order]
        return np.array([np.interp(when, ts, ps[:, 0]), np.interp(when, ts, ps[:, 1])])

    def _pair_terms(
        self, dets: DetectionArrays, t: float, x: np.ndarray, cov: np.ndarray
    ) -> tuple[Projection, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Projection, per-pair measurement, noise, squared Mahalanobis distance, ln|S|."""
        proj = self.ukf.project(x, cov, self.measurement.hx)
        if isinstance(self.measurement, PositionVelocityMeasurement):
            z, r = self._velocity_terms(dets, t)
        else:
            z = np.broadcast_to(dets.xy, (len(x), *dets.xy.shape))
            r = np.broadcast_to(self.measurement.noise(dets.distance), (len(x), len(dets), 2, 2))
        resid = z - proj.z[:, None, :]
        d2, logdet = mahalanobis(resid, proj.pzz[:, None], r)
        return proj, z, r, d2, logdet

    def _associate_and_update(
        self, dets: DetectionArrays, t: float
    ) -> tuple[np.ndarray, np.ndarray]:
        tb = self.table
        assigned = np.zeros(len(dets), dtype=bool)
        in_gate = np.zeros(len(dets), dtype=bool)
        if not len(tb) or not len(dets):
            return assigned, in_gate
        proj, z, r, d2, logdet = self._pair_terms(dets, t, tb.x, tb.cov)
        allowed = self.gater.gate(d2)
        in_gate = allowed.any(axis=0)
        # A weak detection (clutter-like) may refine a track that is being seen, but may
        # not capture a lost track whose gate has grown wide.
        weak = dets.confidence < self.initiator.min_confidence
        lost = t - tb.last_seen > self.visibility_timeout_s
        allowed &= ~(lost[:, None] & weak[None, :])
        cost = self._base_cost(d2, logdet, dets)
        for term in self.cost_terms:
            cost = cost + term.cost(self, dets)
        # Confirmed tracks choose first; tentative tracks only get what is left, so a
        # track born from clutter can never take a detection from a real person's track.
        pairs = []
        taken = np.zeros(len(dets), dtype=bool)
        for stage in (tb.confirmed, ~tb.confirmed):
            rows_in = np.flatnonzero(stage)
            if not len(rows_in):
                continue
            stage_allowed = allowed[rows_in] & ~taken[None, :]
            for i, j in self.associator.associate(cost[rows_in], stage_allowed):
                pairs.append((int(rows_in[i]), j))
                taken[j] = True
        if not pairs:
            return assigned, in_gate
        rows = np.array([p[0] for p in pairs])
        cols = np.array([p[1] for p in pairs])
        sub = Projection(z=proj.z[rows], pzz=proj.pzz[rows], pxz=proj.pxz[rows])
        tb.x[rows], tb.cov[rows] = self.ukf.update(
            tb.x[rows], tb.cov[rows], sub, z[rows, cols], r[rows, cols]
        )
        self._absorb(rows, cols, dets, t)
        assigned[cols] = True
        return assigned, in_gate

    def _base_cost(self, d2: np.ndarray, logdet: np.ndarray, dets: DetectionArrays) -> np.ndarray:
        """Negative log-likelihood of each pair (up to a constant), plus the detector term.

        ``d2 + ln|S|``: an uncertain track (tentative, or unseen for a while) has a wide
        gate but pays for it, so it cannot take a detection from a track that predicts it
        well (plain Mahalanobis distance would favour the uncertain one).
        """
        return d2 + logdet + self.detector_weight * dets.confidence[None, :]

    def _absorb(self, rows: np.ndarray, cols: np.ndarray, dets: DetectionArrays, t: float) -> None:
        """Bookkeeping of tracks that got a detection at time ``t``."""
        tb = self.table
        a = self.height_smoothing
        tb.height[rows] = (1 - a) * tb.height[rows] + a * dets.height[cols]
        tb.z[rows] = (1 - a) * tb.z[rows] + a * dets.z[cols]
        tb.confidence[rows] = 0.8 * tb.confidence[rows] + 0.2 * dets.confidence[cols]
        # Only confident detections keep a track alive (OpenPTrack's "last high-confidence
        # detection"): a lost track cannot live on clutter falling into its wide gate.
        confident = dets.confidence[cols] >= self.initiator.min_confidence
        tb.last_seen[rows[confident]] = np.maximum(tb.last_seen[rows[confident]], t)
        tb.hits[rows] += confident
        # history of posterior positions, at most one entry per spacing interval; the
        # oldest (or an empty) slot is overwritten
        due = rows[t - tb.hist_t[rows].max(axis=1) >= _HISTORY_SPACING_S]
        slots = np.argmin(tb.hist_t[due], axis=1)
        tb.hist_t[due, slots] = t
        tb.hist_xy[due, slots] = tb.x[due, 0:2]

    def _start_tracks(
        self, dets: DetectionArrays, assigned: np.ndarray, in_gate: np.ndarray, t: float
    ) -> None:
        new = self.initiator.initiate(dets.confidence, assigned, in_gate)
        room = self.max_tracks - len(self.table)
        if room <= 0 or not len(new):
            return
        new = new[:room]
        n = len(new)
        ids = np.arange(self.max_id + 1, self.max_id + 1 + n, dtype=np.int64)
        self.max_id += n
        self.counters["tracks_started"] += n
        x = np.zeros((n, 4))
        x[:, 0:2] = dets.xy[new]
        pos_var = self._position_model().noise(dets.distance[new])[:, 0, 0]
        cov = np.zeros((n, 4, 4))
        cov[:, 0, 0] = cov[:, 1, 1] = pos_var
        cov[:, 2, 2] = cov[:, 3, 3] = self.initial_velocity_sigma_mps**2
        hist_t = np.full((n, _HISTORY), -np.inf)
        hist_t[:, 0] = t
        hist_xy = np.zeros((n, _HISTORY, 2))
        hist_xy[:, 0] = dets.xy[new]
        self.table.append(
            ids=ids,
            x=x,
            cov=cov,
            z=dets.z[new],
            height=dets.height[new],
            confidence=dets.confidence[new],
            first_seen=np.full(n, t),
            last_seen=np.full(n, t),
            hits=np.ones(n, dtype=np.int64),
            confirmed=np.zeros(n, dtype=bool),
            hist_t=hist_t,
            hist_xy=hist_xy,
        )

    def _lifecycle(self, t: float) -> None:
        tb = self.table
        if not len(tb):
            return
        tb.confirmed = self.initiator.confirm(tb.hits, tb.confirmed)
        gone = self.deleter.delete(t, tb.first_seen, tb.last_seen, tb.confirmed)
        if gone.any():
            self.counters["tracks_deleted"] += int(gone.sum())
            tb.keep(~gone)

    def _position_model(self) -> PositionMeasurement:
        m = self.measurement
        return m.position if isinstance(m, PositionVelocityMeasurement) else m


def build_tracker(
    config: TrackerConfig | None = None, cost_terms: Sequence[CostTerm] = ()
) -> Tracker:
    """Assemble a :class:`Tracker` from a :class:`~openptrack_py.config.TrackerConfig`."""
    cfg = config or TrackerConfig()
    position = PositionMeasurement(cfg.measurement_sigma_m, cfg.measurement_sigma_per_m2)
    measurement: PositionMeasurement | PositionVelocityMeasurement = position
    if cfg.velocity_in_motion_term:
        measurement = PositionVelocityMeasurement(position, cfg.velocity_sigma_mps)
    return Tracker(
        motion=ConstantVelocity(cfg.acceleration_variance),
        measurement=measurement,
        gater=ChiSquareGater(cfg.gate_probability, measurement.dim),
        associator=GlobalNearestNeighbour(),
        initiator=ConfidenceInitiator(
            cfg.min_confidence_initialization, cfg.detections_to_validate
        ),
        deleter=TimeDeleter(cfg.sec_before_fake, cfg.sec_before_old, cfg.tentative_timeout_s),
        detector_weight=cfg.detector_weight,
        min_confidence_detections=cfg.min_confidence_detections,
        visibility_timeout_s=cfg.visibility_timeout_s,
        initial_velocity_sigma_mps=cfg.initial_velocity_sigma_mps,
        height_smoothing=cfg.height_smoothing,
        publish_tentative=cfg.publish_tentative,
        publish_unseen_s=cfg.publish_unseen_s,
        late_policy=cfg.late_policy,
        max_lateness_s=cfg.max_lateness_s,
        max_replay_steps=cfg.max_replay_steps,
        max_tracks=cfg.max_tracks,
        cost_terms=cost_terms,
    )
