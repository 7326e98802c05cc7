"""The multi-person tracker: one ``step`` per detection batch.

Each batch is one step:

1. every track is predicted to the batch's capture time with the real ``dt``;
2. each detection is compared with each track by the squared Mahalanobis distance of
   its residual under that track's *predicted* innovation covariance, so the gate
   widens while a person is unseen;
3. pairs outside the chi-square gate are inadmissible;
4. a global nearest-neighbour assignment picks pairs (cost = negative log-likelihood +
   the detector confidence term + the identity role's re-ranking), first among
   confirmed tracks, then among tentative tracks for the detections left;
5. assigned tracks are updated; unexplained confident detections start tentative tracks;
   tentative tracks are confirmed after enough detections; stale tracks are deleted.

Each part is a role (:mod:`openptrack_py.tracking.base`); the tracker composes them and
keeps the track table. A batch captured before the tracker's current time (it arrived
late) is applied exactly by replaying from a snapshot (:mod:`openptrack_py.tracking.replay`,
``late_policy: replay``); a batch later than the history reaches is dropped and counted
(``late_policy: drop`` drops every late batch).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from openptrack_py.messages.detection import DetectionBatch
from openptrack_py.messages.track import Track, TrackBatch, Visibility
from openptrack_py.tracking.base import (
    Associator,
    Deleter,
    Gater,
    IdentityModel,
    Initiator,
    MeasurementModel,
    Merger,
    MotionModel,
    SensorModel,
    Stateful,
)
from openptrack_py.tracking.gating import mahalanobis
from openptrack_py.tracking.identity import NullIdentity
from openptrack_py.tracking.merging import NoMerging
from openptrack_py.tracking.replay import ReplayHistory
from openptrack_py.tracking.sensor_model import SensorUpdates, StaticSensorModel
from openptrack_py.tracking.state import (
    HISTORY,
    HISTORY_SPACING_S,
    DetectionArrays,
    LostTracks,
    TrackTable,
)
from openptrack_py.tracking.ukf import MerweSigmaPoints, Projection, UnscentedKalmanFilter

log = logging.getLogger(__name__)

RECENT_WEIGHT = 0.3
"""Weight of a new detection in a track's recent detected position (``recent_xy``)."""
BIRTH_DETECTIONS = 5
"""Detections averaged into where a track started (``TrackTable.birth_xy``)."""
REACQUIRE_S = 10.0
"""How long a lost confirmed track is remembered, so a person seen again there is known."""
REACQUIRE_RADIUS_M = 0.5
REACQUIRE_SPEED_MPS = 0.2
"""A person lost ``dt`` ago is looked for within ``radius + speed * dt`` of where they
were: someone who was hidden, not anyone who could have walked anywhere."""


@dataclass(frozen=True)
class _Snapshot:
    """The tracker's whole state before one step."""

    table: TrackTable
    lost: LostTracks
    time: float | None
    max_id: int
    started: int
    deleted: int
    roles: tuple[Any, ...]


class Tracker:
    """Tracks people on the ground plane from detection batches of any number of sensors.

    Parameters
    ----------
    motion : MotionModel
        Motion model.
    measurement : MeasurementModel
        Measurement model.
    gater : Gater
        Gate; its ``dof`` must equal the measurement dimension.
    associator : Associator
        Picks one-to-one pairs.
    initiator : Initiator
        Starts and confirms tracks.
    deleter : Deleter
        Ends tracks.
    sensors : SensorModel, optional
        What is learned about each sensor (noise, bias, coverage);
        :class:`~openptrack_py.tracking.sensor_model.StaticSensorModel` if omitted.
    merger : Merger, optional
        Merges tracks that follow one person; none if omitted.
    identity : IdentityModel, optional
        Who each track is; :class:`~openptrack_py.tracking.identity.NullIdentity` if omitted.
    detector_weight : float
        Weight of detection confidence in the association cost.
    min_confidence_detections : float
        Detections below this confidence are ignored.
    min_confidence_keepalive : float
        Only detections at least this confident keep a track alive, count towards its
        confirmation, or may capture a lost track (OpenPTrack's "last high-confidence
        detection").
    confidence_decay_s : float
        A published track's confidence falls linearly to 0 over this long unseen.
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
    publish_min_support : float
        Leave out of the output tracks whose support has fallen below this (they stay
        alive, and come back with their id when the evidence does).
    late_policy : {"replay", "drop"}
        Out-of-sequence batches: replay from the last snapshot before them, or drop.
    max_lateness_s : float
        How far back snapshots reach; later batches are dropped.
    max_replay_steps : int
        A late batch that would replay more steps than this is dropped.
    max_tracks : int
        No new track starts while this many exist.
    support_rate : float
        Weight of one expected frame in a track's support (see ``TrackTable.support``).
    multi_sensor_s : float
        A track detected by two sensors in a row within this long is seen by several.
    keepalive_min_support : float
        A confident detection keeps a track alive only if the track's support (before
        that detection) is at least this.
    unseen_stop_s : float
        Time constant of the velocity decay of unseen tracks (0: none).
    shared_noise_factor : float
        Factor on the noise of a detection that two confirmed tracks could both have
        produced (two people in one blob), so it drags its track less.

    Examples
    --------
    >>> from openptrack_py.tracking import build_tracker
    >>> tracker = build_tracker()
    >>> out = tracker.step(batch)  # doctest: +SKIP
    """

    def __init__(
        self,
        motion: MotionModel,
        measurement: MeasurementModel,
        gater: Gater,
        associator: Associator,
        initiator: Initiator,
        deleter: Deleter,
        sensors: SensorModel | None = None,
        merger: Merger | None = None,
        identity: IdentityModel | None = None,
        *,
        detector_weight: float = -1.0,
        min_confidence_detections: float = 0.0,
        min_confidence_keepalive: float = 0.0,
        confidence_decay_s: float = 1.0,
        visibility_timeout_s: float = 0.25,
        initial_velocity_sigma_mps: float = 1.5,
        height_smoothing: float = 0.1,
        publish_tentative: bool = False,
        publish_unseen_s: float = 0.5,
        publish_min_support: float = 0.0,
        late_policy: str = "replay",
        max_lateness_s: float = 1.0,
        max_replay_steps: int = 64,
        max_tracks: int = 1000,
        support_rate: float = 0.2,
        multi_sensor_s: float = 1.0,
        keepalive_min_support: float = 0.0,
        unseen_stop_s: float = 0.0,
        shared_noise_factor: float = 1.0,
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
        if not confidence_decay_s > 0:
            raise ValueError(f"Tracker: confidence_decay_s must be > 0, got {confidence_decay_s}")
        self.motion = motion
        self.measurement = measurement
        self.gater = gater
        self.associator = associator
        self.initiator = initiator
        self.deleter = deleter
        self.sensors: SensorModel = sensors if sensors is not None else StaticSensorModel()
        self.merger: Merger = merger if merger is not None else NoMerging()
        self.identity: IdentityModel = identity if identity is not None else NullIdentity()
        self.support_rate = support_rate
        self.multi_sensor_s = multi_sensor_s
        self.keepalive_min_support = keepalive_min_support
        self.unseen_stop_s = unseen_stop_s
        self.shared_noise_factor = shared_noise_factor
        self._sensor_index: dict[str, int] = {}
        self._stateful_cache: tuple[tuple[int, ...], list[bool]] | None = None
        self.detector_weight = detector_weight
        self.min_confidence_detections = min_confidence_detections
        self.min_confidence_keepalive = min_confidence_keepalive
        self.confidence_decay_s = confidence_decay_s
        self.visibility_timeout_s = visibility_timeout_s
        self.initial_velocity_sigma_mps = initial_velocity_sigma_mps
        self.height_smoothing = height_smoothing
        self.publish_tentative = publish_tentative
        self.publish_unseen_s = publish_unseen_s
        self.publish_min_support = publish_min_support
        self.late_policy = late_policy
        self.max_tracks = max_tracks
        self.history: ReplayHistory[_Snapshot] = ReplayHistory(max_lateness_s, max_replay_steps)
        self.ukf = UnscentedKalmanFilter(MerweSigmaPoints(4))
        self.table = TrackTable()
        self.lost = LostTracks()
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
                "tracks_merged",
                "tracks_reattached",
            ),
            0,
        )

    @property
    def roles(self) -> tuple[object, ...]:
        """Every role, in constructor order."""
        return (
            self.motion,
            self.measurement,
            self.gater,
            self.associator,
            self.initiator,
            self.deleter,
            self.sensors,
            self.merger,
            self.identity,
        )

    def _stateful(self) -> list[tuple[object, bool]]:
        """Every role with whether it keeps state of its own (looked up once per role)."""
        roles = self.roles
        if self._stateful_cache is None or self._stateful_cache[0] != tuple(map(id, roles)):
            flags = [isinstance(r, Stateful) for r in roles]
            self._stateful_cache = (tuple(map(id, roles)), flags)
        return list(zip(roles, self._stateful_cache[1], strict=True))

    # ------------------------------------------------------------------- public

    def step(self, batch: DetectionBatch) -> TrackBatch:
        """Apply one detection batch; return the tracks after it."""
        self.counters["steps"] += 1
        if self.time is not None and batch.stamp < self.time:
            self._apply_late(batch)
            return self.output(self.time)
        self._advance(batch)
        return self.output(batch.stamp)

    def adopt_state(self, other: Tracker) -> None:
        """Take over ``other``'s tracks, clock and id counter (after a reconfiguration).

        Roles keep their state across a reconfiguration when both trackers have a
        stateful role of the same kind in the same place.
        """
        self.table = other.table
        self.lost = other.lost
        self.time = other.time
        self.max_id = other.max_id
        self.seq = other.seq
        self.frame_id = other.frame_id
        self.counters = other.counters
        for mine, theirs in zip(self.roles, other.roles, strict=True):
            if isinstance(mine, Stateful) and type(mine) is type(theirs):
                mine.restore(theirs.snapshot())  # type: ignore[attr-defined]

    def output(self, t: float) -> TrackBatch:
        """The tracks as a message (confirmed ones unless ``publish_tentative``)."""
        tb = self.table
        self.seq += 1
        unseen = t - tb.last_seen
        shown = (unseen <= self.publish_unseen_s) & (tb.support >= self.publish_min_support)
        if not self.publish_tentative:
            shown &= tb.confirmed
        rows = np.flatnonzero(shown)
        fresh = np.clip(1.0 - unseen[rows] / self.confidence_decay_s, 0.0, 1.0)
        evidence = tb.confidence[rows] * tb.support[rows] * fresh
        columns = zip(
            tb.ids[rows].tolist(),
            tb.x[rows].tolist(),
            tb.z[rows].tolist(),
            tb.height[rows].tolist(),
            np.maximum(t - tb.first_seen[rows], 0.0).tolist(),
            np.clip(evidence, 0.0, 1.0).tolist(),
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
            tracks=tuple(self.identity.annotate(tracks)),
            alive_ids=tuple(tb.ids.tolist()),
            max_id=self.max_id,
        )

    # ------------------------------------------------------- steps and replays

    def _advance(self, batch: DetectionBatch) -> None:
        """One in-order step, remembered for replays."""
        t = batch.stamp
        if self.late_policy == "replay" and self.history.max_lateness_s > 0:
            self.history.remember(t, self._snapshot(), batch)
        dets = DetectionArrays.from_batch(batch, self.min_confidence_detections)
        dets = self.sensors.correct(dets)
        self._predict_to(t)
        assigned, d2 = self._associate_and_update(dets, t)
        self._start_tracks(dets, assigned, d2, t)
        self._lifecycle(t)

    def _snapshot(self) -> _Snapshot:
        c = self.counters
        roles = tuple(r.snapshot() if stateful else None for r, stateful in self._stateful())
        return _Snapshot(
            self.table.copy(), self.lost.copy(), self.time, self.max_id, c["tracks_started"],
            c["tracks_deleted"], roles,
        )  # fmt: skip

    def _restore(self, snapshot: _Snapshot) -> None:
        self.table, self.time, self.max_id = snapshot.table, snapshot.time, snapshot.max_id
        self.lost = snapshot.lost
        # what happened after the snapshot is undone, and will be counted again on replay
        self.counters["tracks_started"] = snapshot.started
        self.counters["tracks_deleted"] = snapshot.deleted
        for (role, stateful), state in zip(self._stateful(), snapshot.roles, strict=True):
            if stateful:
                role.restore(state)  # type: ignore[attr-defined]

    def _apply_late(self, batch: DetectionBatch) -> None:
        """Replay from the last state before ``batch``'s capture, or drop it."""
        assert self.time is not None
        rewind = None
        if self.late_policy == "replay":
            rewind = self.history.rewind(batch, self.time, lambda s: s.time)
        if rewind is None:
            self.counters["late_dropped"] += 1
            return
        self.counters["late_applied"] += 1
        self._restore(rewind.state)
        self.counters["replayed_steps"] += len(rewind.batches) - 1
        for queued in rewind.batches:
            self._advance(queued)

    # --------------------------------------------------------------- internals

    def _predict_to(self, t: float) -> None:
        tb = self.table
        if self.time is not None and len(tb) and t > self.time:
            dt = np.full(len(tb), t - self.time)
            tb.x, tb.cov = self.ukf.predict(
                tb.x, tb.cov, dt, self.motion.fx, self.motion.noise(dt)
            )
            self._damp_unseen(t, dt[0])
        self.time = t if self.time is None else max(self.time, t)

    def _damp_unseen(self, t: float, dt: float) -> None:
        """A person nobody sees is more likely to slow down than to walk on for ever.

        While a track is unseen its velocity decays with time constant
        ``unseen_stop_s`` (its covariance with it), so a track does not coast across the
        room after someone who stopped or turned where no sensor sees them.
        """
        if self.unseen_stop_s <= 0:
            return
        tb = self.table
        unseen = t - tb.last_seen > self.visibility_timeout_s
        if not unseen.any():
            return
        k = math.exp(-dt / self.unseen_stop_s)
        f = np.diag([1.0, 1.0, k, k])
        tb.x[unseen] = tb.x[unseen] @ f
        tb.cov[unseen] = f @ tb.cov[unseen] @ f

    def _pair_terms(
        self, dets: DetectionArrays, t: float
    ) -> tuple[Projection, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Projection, per-pair measurement, noise, squared Mahalanobis distance, ln|S|."""
        tb = self.table
        proj = self.ukf.project(tb.x, tb.cov, self.measurement.hx)
        z, r = self.measurement.pair_measurements(dets, tb, t)
        scale = self.sensors.noise_scale(dets.sensor_id, dets.distance)
        if (scale != 1.0).any():
            r = r.copy()
            r[..., 0:2, 0:2] *= scale[None, :, None, None]
        resid = z - proj.z[:, None, :]
        d2, logdet = mahalanobis(resid, proj.pzz[:, None], r)
        return proj, z, r, d2, logdet

    def _associate_and_update(
        self, dets: DetectionArrays, t: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Assign and update; return the assigned-detection mask and every pair's ``d2``."""
        tb = self.table
        assigned = np.zeros(len(dets), dtype=bool)
        if not len(tb) or not len(dets):
            self._update_support(np.zeros(0, dtype=int), dets.sensor_id)
            self.sensors.observe_frame(dets.sensor_id, len(dets))
            return assigned, np.zeros((len(tb), len(dets)))
        proj, z, r, d2, logdet = self._pair_terms(dets, t)
        allowed = self.gater.gate(d2)
        gated = allowed.copy()
        # A weak detection (clutter-like) may refine a track that is being seen, but may
        # not capture a lost track whose gate has grown wide.
        weak = dets.confidence < self.min_confidence_keepalive
        lost = t - tb.last_seen > self.visibility_timeout_s
        allowed &= ~(lost[:, None] & weak[None, :])
        if self.measurement.dim == 2:
            # a track only takes a detection it explains better than clutter does:
            # N(nu; 0, S) >= clutter density, i.e. d2 + ln|S| <= -2 ln(2 pi density)
            density = self.sensors.clutter_density(dets.sensor_id)
            if density > 0:
                allowed &= d2 + logdet <= -2.0 * math.log(2.0 * math.pi * density)
        cost = self._base_cost(d2, logdet, dets)
        extra = self.identity.cost(tb, dets, t)
        if extra is not None:
            cost = cost + extra
        pairs = self._assign_by_stage(cost, allowed)
        if not pairs:
            self._update_support(np.zeros(0, dtype=int), dets.sensor_id)
            self.sensors.observe_frame(dets.sensor_id, len(dets))
            return assigned, d2
        rows = np.array([p[0] for p in pairs])
        cols = np.array([p[1] for p in pairs])
        scale = self.sensors.noise_scale(dets.sensor_id, dets.distance)[cols]
        self._learn(
            rows, cols, dets, proj.z[rows, 0:2], proj.pzz[rows, 0:2, 0:2],
            r[rows, cols, 0:2, 0:2] / scale[:, None, None], gated, t,
        )  # fmt: skip
        sub = Projection(z=proj.z[rows], pzz=proj.pzz[rows], pxz=proj.pxz[rows])
        r_used = r[rows, cols]
        if self.shared_noise_factor > 1.0:
            # a detection two confirmed tracks could both have produced may be both
            # people in one blob: it pulls its track less, so neither is dragged onto
            # the other's course
            shared = (gated[:, cols] & tb.confirmed[:, None]).sum(axis=0) >= 2
            if shared.any():
                r_used = r_used.copy()
                r_used[shared] *= self.shared_noise_factor
        tb.x[rows], tb.cov[rows] = self.ukf.update(
            tb.x[rows], tb.cov[rows], sub, z[rows, cols], r_used
        )
        prior_support = tb.support[rows].copy()
        self._update_support(rows, dets.sensor_id)
        self._absorb(rows, cols, dets, t, prior_support)
        self.merger.observe(tb, rows, t)
        self.identity.observe(tb, rows, cols, dets, t)
        assigned[cols] = True
        self.sensors.observe_frame(dets.sensor_id, int((~assigned).sum()))
        return assigned, d2

    def _learn(
        self,
        rows: np.ndarray,
        cols: np.ndarray,
        dets: DetectionArrays,
        predicted: np.ndarray,
        pzz: np.ndarray,
        model: np.ndarray,
        gated: np.ndarray,
        t: float,
    ) -> None:
        """Hand the sensor model this batch's unambiguous updates of settled tracks."""
        tb = self.table
        clear = (
            tb.confirmed[rows]
            & (t - tb.first_seen[rows] >= 1.0)
            & (gated[rows].sum(axis=1) == 1)
            & (gated[:, cols].sum(axis=0) == 1)
        )
        if not clear.any():
            return
        index = self._sensor_index.get(dets.sensor_id, -1)
        multi = (t - tb.multi_t[rows] <= self.multi_sensor_s) | (tb.last_sensor[rows] != index)
        pzz, model, kept = pzz[clear], model[clear], cols[clear]
        self.sensors.learn(
            SensorUpdates(
                sensor_id=dets.sensor_id,
                detected=dets.xy[kept],
                predicted=predicted[clear],
                distance=dets.distance[kept],
                track_var=0.5 * (pzz[:, 0, 0] + pzz[:, 1, 1]),
                model_var=0.5 * (model[:, 0, 0] + model[:, 1, 1]),
                gate=float(self.gater.threshold),
                multi_sensor=multi[clear],
            )
        )

    def _update_support(self, hit_rows: np.ndarray, sensor_id: str) -> None:
        """Tracks this sensor should have seen gain support if detected, lose it if not."""
        tb = self.table
        if not len(tb):
            return
        expected = self.sensors.covers(sensor_id, tb.x[:, 0:2])
        hit = np.zeros(len(tb), dtype=bool)
        hit[hit_rows] = True
        expected |= hit
        a = self.support_rate
        tb.support[expected] += a * (hit[expected] - tb.support[expected])

    def _assign_by_stage(self, cost: np.ndarray, allowed: np.ndarray) -> list[tuple[int, int]]:
        """Confirmed tracks choose first; tentative tracks only get what is left.

        A track born from clutter can therefore never take a detection from a real
        person's track.
        """
        confirmed = self.table.confirmed
        pairs = []
        taken = np.zeros(cost.shape[1], dtype=bool)
        for stage in (confirmed, ~confirmed):
            rows_in = np.flatnonzero(stage)
            if not len(rows_in):
                continue
            stage_allowed = allowed[rows_in] & ~taken[None, :]
            for i, j in self.associator.associate(cost[rows_in], stage_allowed):
                pairs.append((int(rows_in[i]), j))
                taken[j] = True
        return pairs

    def _base_cost(self, d2: np.ndarray, logdet: np.ndarray, dets: DetectionArrays) -> np.ndarray:
        """Negative log-likelihood of each pair (up to a constant), plus the detector term.

        ``d2 + ln|S|``: an uncertain track (tentative, or unseen for a while) has a wide
        gate but pays for it, so it cannot take a detection from a track that predicts it
        well (plain Mahalanobis distance would favour the uncertain one).
        """
        return d2 + logdet + self.detector_weight * dets.confidence[None, :]

    def _absorb(
        self,
        rows: np.ndarray,
        cols: np.ndarray,
        dets: DetectionArrays,
        t: float,
        prior_support: np.ndarray,
    ) -> None:
        """Bookkeeping of tracks that got a detection at time ``t``."""
        tb = self.table
        a = self.height_smoothing
        tb.height[rows] = (1 - a) * tb.height[rows] + a * dets.height[cols]
        tb.z[rows] = (1 - a) * tb.z[rows] + a * dets.z[cols]
        tb.confidence[rows] = 0.8 * tb.confidence[rows] + 0.2 * dets.confidence[cols]
        # Only confident detections keep a track alive (OpenPTrack's "last high-confidence
        # detection"), and only while the track's support holds: a lost track whose
        # gate has grown wide cannot live on a confident false positive now and then.
        confident = dets.confidence[cols] >= self.min_confidence_keepalive
        confident &= prior_support >= self.keepalive_min_support
        tb.last_seen[rows[confident]] = np.maximum(tb.last_seen[rows[confident]], t)
        tb.hits[rows] += confident
        b = RECENT_WEIGHT
        tb.recent_xy[rows] = (1 - b) * tb.recent_xy[rows] + b * dets.xy[cols]
        # where the track started: the mean of its first few detections
        young = tb.birth_n[rows] < BIRTH_DETECTIONS
        yr, yc = rows[young], cols[young]
        n = tb.birth_n[yr][:, None]
        tb.birth_xy[yr] = (tb.birth_xy[yr] * n + dets.xy[yc]) / (n + 1)
        tb.birth_n[yr] += 1
        # which sensors see it: detections from two sensors in a row
        index = self._sensor_index.setdefault(dets.sensor_id, len(self._sensor_index))
        other = tb.last_sensor[rows] != index
        tb.multi_t[rows[other]] = t
        tb.last_sensor[rows] = index
        # history of posterior positions, at most one entry per spacing interval; the
        # oldest (or an empty) slot is overwritten
        due = rows[t - tb.hist_t[rows].max(axis=1) >= HISTORY_SPACING_S]
        slots = np.argmin(tb.hist_t[due], axis=1)
        tb.hist_t[due, slots] = t
        tb.hist_xy[due, slots] = tb.x[due, 0:2]

    def _start_tracks(
        self, dets: DetectionArrays, assigned: np.ndarray, d2: np.ndarray, t: float
    ) -> None:
        new = self.initiator.initiate(dets, assigned, d2, self.table)
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
        pos_var = self.measurement.position_noise(dets.distance[new])[:, 0, 0]
        cov = np.zeros((n, 4, 4))
        cov[:, 0, 0] = cov[:, 1, 1] = pos_var
        cov[:, 2, 2] = cov[:, 3, 3] = self.initial_velocity_sigma_mps**2
        hist_t = np.full((n, HISTORY), -np.inf)
        hist_t[:, 0] = t
        hist_xy = np.zeros((n, HISTORY, 2))
        hist_xy[:, 0] = dets.xy[new]
        first = len(self.table)
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
            support=np.ones(n),
            birth_xy=dets.xy[new].copy(),
            recent_xy=dets.xy[new].copy(),
            birth_n=np.ones(n, dtype=np.int64),
            last_sensor=np.full(
                n, self._sensor_index.setdefault(dets.sensor_id, len(self._sensor_index))
            ),
            multi_t=np.full(n, -np.inf),
            reborn=self.lost.near(dets.xy[new], t, REACQUIRE_RADIUS_M, REACQUIRE_SPEED_MPS),
        )
        self.identity.started(self.table, np.arange(first, first + n), dets.subset(new), t)

    def _lifecycle(self, t: float) -> None:
        tb = self.table
        if not len(tb):
            return
        was = tb.confirmed
        tb.confirmed = self.initiator.confirm(tb, t)
        self._reattach(t, np.flatnonzero(tb.confirmed & ~was))
        self._merge(t)
        gone = self.deleter.delete(tb, t)
        self.lost.forget_before(t - REACQUIRE_S)
        if gone.any():
            self.lost.add(tb.x[gone & tb.confirmed, 0:2], t)
            self.identity.ended(tb, np.flatnonzero(gone), t)
            self.counters["tracks_deleted"] += int(gone.sum())
            tb.keep(~gone)

    def _merge(self, t: float) -> None:
        """Fold each track that follows the same person as an older one into it."""
        pairs = self.merger.merge(self.table, t)
        if not pairs:
            return
        tb = self.table
        keep = np.array([p[0] for p in pairs])
        drop = np.array([p[1] for p in pairs])
        # the kept track moves to the information-weighted mean of both positions
        pk, pd = tb.cov[keep, 0:2, 0:2], tb.cov[drop, 0:2, 0:2]
        ik, idr = np.linalg.inv(pk), np.linalg.inv(pd)
        fused = np.linalg.solve(
            ik + idr,
            (ik @ tb.x[keep, 0:2, None] + idr @ tb.x[drop, 0:2, None]),
        )[..., 0]
        tb.x[keep, 0:2] = fused
        tb.first_seen[keep] = np.minimum(tb.first_seen[keep], tb.first_seen[drop])
        tb.last_seen[keep] = np.maximum(tb.last_seen[keep], tb.last_seen[drop])
        tb.hits[keep] += tb.hits[drop]
        tb.support[keep] = np.maximum(tb.support[keep], tb.support[drop])
        tb.confidence[keep] = np.maximum(tb.confidence[keep], tb.confidence[drop])
        self.identity.ended(tb, drop, t)
        self.counters["tracks_merged"] += len(drop)
        self.counters["tracks_deleted"] += len(drop)
        mask = np.ones(len(tb), dtype=bool)
        mask[drop] = False
        tb.keep(mask)

    def _reattach(self, t: float, new: np.ndarray) -> None:
        """A track confirmed now takes the id of the lost track its person had."""
        pairs = self.merger.reattach(self.table, t, new, self.visibility_timeout_s)
        if not pairs:
            return
        tb = self.table
        lost = np.array([p[0] for p in pairs])
        found = np.array([p[1] for p in pairs])
        self.identity.ended(tb, found, t)
        tb.ids[found] = tb.ids[lost]
        tb.first_seen[found] = tb.first_seen[lost]
        self.counters["tracks_reattached"] += len(pairs)
        self.counters["tracks_deleted"] += len(pairs)
        mask = np.ones(len(tb), dtype=bool)
        mask[lost] = False
        tb.keep(mask)
