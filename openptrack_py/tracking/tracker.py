"""The multi-person tracker: one ``step`` per detection batch.

Each batch is one step:

1. every track is predicted to the batch's capture time with the real ``dt``;
2. each detection is compared with each track by the squared Mahalanobis distance of its
   residual under the track's *predicted* innovation covariance (wider while unseen);
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
from openptrack_py.messages.track import TrackBatch
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
from openptrack_py.tracking.blobs import keep_apart, share_blobs, shared_noise, slow_approaches
from openptrack_py.tracking.bookkeeping import (
    absorb,
    damp_unseen,
    fold_into,
    learnable_updates,
    new_rows,
    renumber,
    take_over,
    update_support,
)
from openptrack_py.tracking.gating import mahalanobis
from openptrack_py.tracking.identity.null import NullIdentity
from openptrack_py.tracking.merging import NoMerging
from openptrack_py.tracking.params import TrackerParams
from openptrack_py.tracking.publish import published_tracks
from openptrack_py.tracking.replay import ReplayHistory
from openptrack_py.tracking.state import DetectionArrays, TrackTable, sensor_slot
from openptrack_py.tracking.static_sensors import StaticSensorModel
from openptrack_py.tracking.ukf import MerweSigmaPoints, Projection, UnscentedKalmanFilter

log = logging.getLogger(__name__)

COUNTERS = (
    "steps", "late_applied", "late_dropped", "replayed_steps", "tracks_started",
    "tracks_deleted", "tracks_merged", "tracks_reattached", "tracks_split",
)  # fmt: skip
"""The tracker's counters (reported in the tracker node's stats)."""


@dataclass(frozen=True)
class _Snapshot:
    """The tracker's whole state before one step."""

    table: TrackTable
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
        :class:`~openptrack_py.tracking.static_sensors.StaticSensorModel` if omitted.
    merger : Merger, optional
        Merges tracks that follow one person; none if omitted.
    identity : IdentityModel, optional
        Who each track is; :class:`~openptrack_py.tracking.identity.NullIdentity` if omitted.
    params : TrackerParams, optional
        Every setting that is not a role (defaults if omitted).

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
        params: TrackerParams | None = None,
    ) -> None:
        if gater.dof != measurement.dim:
            raise ValueError(
                f"Tracker: gater.dof ({gater.dof}) must equal the measurement dimension "
                f"({measurement.dim})"
            )
        self.motion = motion
        self.measurement = measurement
        self.gater = gater
        self.associator = associator
        self.initiator = initiator
        self.deleter = deleter
        self.sensors: SensorModel = sensors if sensors is not None else StaticSensorModel()
        self.merger: Merger = merger if merger is not None else NoMerging()
        self.identity: IdentityModel = identity if identity is not None else NullIdentity()
        self.params = params if params is not None else TrackerParams()
        p = self.params
        self.history = ReplayHistory[_Snapshot](p.max_lateness_s, p.max_replay_steps)
        self.ukf = UnscentedKalmanFilter(MerweSigmaPoints(4))
        self.table = TrackTable()
        self.time: float | None = None
        self.max_id = self.max_published_id = 0
        self.seq, self.frame_id = 0, "world"
        self.counters: dict[str, int] = dict.fromkeys(COUNTERS, 0)
        self.sensor_index: dict[str, int] = {}  # sensor id -> its column in the table
        self._stateful_cache: tuple[tuple[int, ...], list[bool]] | None = None

    @property
    def roles(self) -> tuple[object, ...]:
        """Every role, in constructor order."""
        return (self.motion, self.measurement, self.gater, self.associator, self.initiator,
                self.deleter, self.sensors, self.merger, self.identity)  # fmt: skip

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
        source = (batch.sensor_id, batch.seq, batch.stamp)
        if self.time is not None and batch.stamp < self.time:
            self._apply_late(batch)
            return self.output(self.time, source)
        self._advance(batch)
        return self.output(batch.stamp, source)

    def adopt_state(self, other: Tracker) -> None:
        """Take over ``other``'s tracks, sensor order, clock and ids (after a reconfiguration).

        Roles keep their state across a reconfiguration when both trackers have a
        stateful role of the same kind in the same place.
        """
        self.table = other.table
        self.time = other.time
        self.max_id = other.max_id
        self.max_published_id = other.max_published_id
        self.seq = other.seq
        self.frame_id = other.frame_id
        self.counters = other.counters
        self.sensor_index = dict(other.sensor_index)  # the table's sensor columns
        for mine, theirs in zip(self.roles, other.roles, strict=True):
            if isinstance(mine, Stateful) and type(mine) is type(theirs):
                mine.restore(theirs.snapshot())  # type: ignore[attr-defined]

    def snapshot(self) -> _Snapshot:
        """The tracker's whole state now (independent of the live one): for checkpoints."""
        return self._snapshot()

    def restore_state(self, table: TrackTable, time: float | None, roles: tuple[Any, ...]) -> None:
        """Take a track table, a clock and the roles' snapshots (from a checkpoint).

        The checkpoint comes from a tracker of the same configuration; a role whose
        snapshot does not fit starts afresh.
        """
        self.table, self.time = table, time
        for (role, stateful), state in zip(self._stateful(), roles, strict=False):
            if stateful and state is not None:
                try:
                    role.restore(state)  # type: ignore[attr-defined]
                except Exception:  # a role changed since: it starts afresh
                    log.warning("tracker role %s could not resume its state", type(role).__name__)

    def output(self, t: float, source: tuple[str, int, float] | None = None) -> TrackBatch:
        """The tracks as a message (confirmed ones unless ``publish_tentative``).

        ``alive_ids`` are exactly the ids of the tracks in the message and ``max_id``
        the highest id ever published: a client never hears of an id it was not shown.
        ``source`` names the batch the step applied (sensor id, ``seq``, stamp).
        """
        self.seq += 1
        tracks = published_tracks(self.table, t, self.params, self.identity.labels)
        ids = tuple(tr.id for tr in tracks)
        self.max_published_id = max(self.max_published_id, *ids, 0)
        return TrackBatch(
            stamp=t,
            seq=self.seq,
            frame_id=self.frame_id,
            tracks=tuple(tracks),
            alive_ids=ids,
            max_id=self.max_published_id,
            source=source,
        )

    # ------------------------------------------------------- steps and replays

    def _advance(self, batch: DetectionBatch) -> None:
        """One in-order step, remembered for replays."""
        t = batch.stamp
        if self.params.late_policy == "replay" and self.history.max_lateness_s > 0:
            self.history.remember(t, self._snapshot(), batch)
        dets = DetectionArrays.from_batch(
            batch, self.params.min_confidence_detections, self.identity.needs_looks
        )
        dets = self.sensors.correct(dets)
        dt = self._predict_to(t)
        assigned, d2 = self._associate_and_update(dets, t, dt)
        self._start_tracks(dets, assigned, d2, t)
        self._lifecycle(t, dets)
        self.sensors.observe_tracks(self.table, t, list(self.sensor_index))

    def _snapshot(self) -> _Snapshot:
        c = self.counters
        roles = tuple(r.snapshot() if stateful else None for r, stateful in self._stateful())
        return _Snapshot(self.table.copy(), self.time, self.max_id, c["tracks_started"],
                         c["tracks_deleted"], roles)  # fmt: skip

    def _restore(self, snapshot: _Snapshot) -> None:
        self.table, self.time, self.max_id = snapshot.table, snapshot.time, snapshot.max_id
        # what happened after the snapshot is undone, and will be counted again on replay
        self.counters.update(tracks_started=snapshot.started, tracks_deleted=snapshot.deleted)
        for (role, stateful), state in zip(self._stateful(), snapshot.roles, strict=True):
            if stateful:
                role.restore(state)  # type: ignore[attr-defined]

    def _apply_late(self, batch: DetectionBatch) -> None:
        """Replay from the last state before ``batch``'s capture, or drop it."""
        assert self.time is not None
        rewind = None
        if self.params.late_policy == "replay":
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

    def _predict_to(self, t: float) -> float:  # returns the time predicted over
        step = 0.0 if self.time is None else max(t - self.time, 0.0)
        if step > 0 and len(self.table):
            tb, dt = self.table, np.full(len(self.table), step)
            tb.x, tb.cov = self.ukf.predict(
                tb.x, tb.cov, dt, self.motion.fx, self.motion.noise(dt)
            )
            damp_unseen(tb, t, step, self.params)
        self.time = t if self.time is None else max(self.time, t)
        return step

    def _pair_terms(
        self, dets: DetectionArrays, t: float
    ) -> tuple[Projection, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Projection, per-pair measurement, noise, squared Mahalanobis distance, ln|S|."""
        tb = self.table
        proj = self.ukf.project(tb.x, tb.cov, self.measurement.hx)
        z, r = self.measurement.pair_measurements(dets, tb, t)
        scale = self.sensors.noise_scale(dets.sensor_id, dets.distance)
        names = list(self.sensor_index)  # by index
        extra = self.sensors.cross_sensor_var(dets.sensor_id, dets.distance, tb.last_sensor, names)
        if (scale != 1.0).any() or extra is not None:
            r = r.copy()
            r[..., 0:2, 0:2] *= scale[None, :, None, None]
            if extra is not None:
                r[..., 0:2, 0:2] += extra[..., None, None] * np.eye(2)
        resid = z - proj.z[:, None, :]
        d2, logdet = mahalanobis(resid, proj.pzz[:, None], r)
        return proj, z, r, d2, logdet

    def _associate_and_update(
        self, dets: DetectionArrays, t: float, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Assign and update (``dt``: since the last step); return the assigned mask and ``d2``."""
        tb = self.table
        assigned = np.zeros(len(dets), dtype=bool)
        if not len(tb) or not len(dets):
            self._update_support(np.zeros(0, dtype=int), dets.sensor_id, t)
            self.sensors.observe_frame(dets.sensor_id, len(dets))
            return assigned, np.zeros((len(tb), len(dets)))
        proj, z, r, d2, logdet = self._pair_terms(dets, t)
        allowed = self.gater.gate(d2)
        gated = allowed.copy()
        # A weak detection (clutter-like) may refine a track that is being seen, but may
        # not capture a lost track whose gate has grown wide.
        weak = dets.confidence < self.params.min_confidence_keepalive
        lost = t - tb.last_seen > self.params.visibility_timeout_s
        allowed &= ~(lost[:, None] & weak[None, :])
        if self.measurement.dim == 2:
            # a track only takes a detection it explains better than clutter does:
            # N(nu; 0, S) >= clutter density, i.e. d2 + ln|S| <= -2 ln(2 pi density)
            density = self.sensors.clutter_density(dets.sensor_id)
            if density > 0:
                allowed &= d2 + logdet <= -2.0 * math.log(2.0 * math.pi * density)
        nll = self._base_cost(d2, logdet, dets)
        extra = self.identity.cost(tb, dets, t, allowed)
        cost = nll if extra is None else nll + extra
        pairs = self._assign_by_stage(cost, allowed)
        if not pairs:
            self._update_support(np.zeros(0, dtype=int), dets.sensor_id, t)
            self.sensors.observe_frame(dets.sensor_id, len(dets))
            return assigned, d2
        rows = np.array([p[0] for p in pairs])
        cols = np.array([p[1] for p in pairs])
        scale = self.sensors.noise_scale(dets.sensor_id, dets.distance)[cols]
        updates = learnable_updates(
            tb, rows, cols, dets, proj.z[rows, 0:2], proj.pzz[rows, 0:2, 0:2],
            r[rows, cols, 0:2, 0:2] / scale[:, None, None], gated, t,
            self.sensor_index.get(dets.sensor_id, -1), float(self.gater.threshold),
            self.params.multi_sensor_s,
        )  # fmt: skip
        if updates is not None:
            self.sensors.learn(updates)
        own_rows, own_cols = rows, cols
        rows, cols, blob = share_blobs(tb, self.identity, dets, rows, cols, d2, gated, t)
        sub = Projection(z=proj.z[rows], pzz=proj.pzz[rows], pxz=proj.pxz[rows])
        r_used = shared_noise(
            r[rows, cols], rows, cols, blob, gated, tb.confirmed,
            self.params.shared_noise_factor, nll if self.params.shared_noise_pda else None,
        )  # fmt: skip
        tb.x[rows], tb.cov[rows] = self.ukf.update(
            tb.x[rows], tb.cov[rows], sub, z[rows, cols], r_used
        )
        slow_approaches(tb, gated, dt, self.params.approach_stop_s)
        keep_apart(tb, *self.merger.distinct_rows(tb, t), self.params.person_gap_m)
        certain = None  # pairs motion alone made certain: each the only one in the other's gate
        if self.identity.needs_looks or self.params.needs_certain_pairs:
            certain = (gated[own_rows].sum(axis=1) == 1) & (gated[:, own_cols].sum(axis=0) == 1)
        sure = None if certain is None else own_rows[certain]
        prior_support = self._update_support(rows, dets.sensor_id, t, sure)
        index = self.sensor_index.setdefault(dets.sensor_id, len(self.sensor_index))
        absorb(tb, rows, cols, dets, t, prior_support, index, self.params)
        apart = (certain,) if self.params.merge_proof_unambiguous else ()  # older mergers: none
        self.merger.observe(
            tb, own_rows, t, r[own_rows, own_cols, :2, :2], sensor_slot(index), *apart
        )
        self.identity.observe(tb, own_rows, own_cols, dets, t, certain)
        assigned[cols] = True
        self.sensors.observe_frame(dets.sensor_id, int((~assigned).sum()))
        return assigned, d2

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
        return d2 + logdet + self.params.detector_weight * dets.confidence[None, :]

    def _start_tracks(
        self, dets: DetectionArrays, assigned: np.ndarray, d2: np.ndarray, t: float
    ) -> None:
        new = self.initiator.initiate(dets, assigned, d2, self.table)
        room = self.params.max_tracks - len(self.table)
        if room <= 0 or not len(new):
            return
        new, n = new[:room], min(room, len(new))
        ids = np.arange(self.max_id + 1, self.max_id + 1 + n, dtype=np.int64)
        self.max_id += n
        self.counters["tracks_started"] += n
        # a new track is as uncertain as its sensor really is (its learned noise)
        pos_var = self.measurement.position_noise(dets.distance[new])[:, 0, 0]
        pos_var = pos_var * self.sensors.noise_scale(dets.sensor_id, dets.distance[new])
        index = self.sensor_index.setdefault(dets.sensor_id, len(self.sensor_index))
        first = len(self.table)
        self.table.append(**new_rows(dets, new, ids, t, pos_var, index, self.params))
        self.identity.started(self.table, np.arange(first, first + n), dets.subset(new), t)

    def _lifecycle(self, t: float, dets: DetectionArrays) -> None:
        tb = self.table
        if not len(tb):
            return
        was = tb.confirmed
        continuing = self.merger.continuations(tb, t, self.params.visibility_timeout_s)
        tb.confirmed = self.initiator.confirm(tb, t, continuing)
        self._reattach(t, np.flatnonzero(tb.confirmed & ~was))
        self._merge(t)
        self._split(t, dets)
        gone = self.deleter.delete(tb, t)
        if gone.any():
            self.identity.ended(tb, np.flatnonzero(gone), t)
            self.counters["tracks_deleted"] += int(gone.sum())
            tb.keep(~gone)

    def _update_support(
        self, hit_rows: np.ndarray, sensor_id: str, t: float, sure: np.ndarray | None = None
    ) -> np.ndarray:
        """One sensor frame moves tracks' support; returns what keeps ``hit_rows`` alive."""
        if not len(self.table):
            return np.zeros(0)
        xy, twin = self.table.x[:, 0:2], self.params.occlusion_twin_m
        expected = self.sensors.covers(sensor_id, xy)
        hidden = self.sensors.hidden(sensor_id, xy, hit_rows, twin) if twin > 0 else None
        index = self.sensor_index.setdefault(sensor_id, len(self.sensor_index))
        return update_support(self.table, hit_rows, expected, index, t, self.params, hidden, sure)

    def _merge(self, t: float) -> None:
        """Fold each track following the person of an older one (not one known apart) into it."""
        pairs = self.merger.merge(self.table, t)
        if pairs:
            keep, drop = (np.array(rows) for rows in zip(*pairs, strict=True))
            two = self.identity.distinct(self.table, keep, drop)
            pairs = [p for p, d in zip(pairs, two.tolist(), strict=True) if not d]
        if pairs:
            keep, drop = (np.array(rows) for rows in zip(*pairs, strict=True))
            self.identity.ended(self.table, drop, t, "merged")
            fold_into(self.table, keep, drop)
            self.counters["tracks_merged"] += len(drop)
            self.counters["tracks_deleted"] += len(drop)

    def _split(self, t: float, dets: DetectionArrays) -> None:
        """A track found to follow someone else since it was lost goes on under a new id."""
        rows = self.identity.handed_over(self.table)
        if len(rows):
            self.identity.ended(self.table, rows, t, "handed over")
            renumber(self.table, rows, self.max_id + 1, t)
            self.max_id += len(rows)
            self.identity.started(self.table, rows, dets, t)
            self.counters["tracks_split"] += len(rows)

    def _reattach(self, t: float, new: np.ndarray) -> None:
        """A track confirmed now takes the id of the lost track its person had."""
        pairs = self.merger.reattach(self.table, t, new, self.params.visibility_timeout_s)
        if pairs:
            lost, found = (np.array(rows) for rows in zip(*pairs, strict=True))
            self.identity.ended(self.table, found, t, "reattached")
            take_over(self.table, lost, found)
            self.counters["tracks_reattached"] += len(pairs)
            self.counters["tracks_deleted"] += len(pairs)
