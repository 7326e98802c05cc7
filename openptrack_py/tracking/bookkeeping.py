"""Bookkeeping of the track table: what a step does to tracks' rows.

Plain functions on :class:`~openptrack_py.tracking.state.TrackTable`, so that the tracker
reads as the sequence of a step (predict, associate, update, start, confirm, merge,
delete) and each piece of bookkeeping can be tested on its own: new rows, absorbing
detections, support, slowing unseen tracks, folding a merged track into the older one, a
track taking over a lost track's id, and which updates a sensor model may learn from.
"""

from __future__ import annotations

import math

import numpy as np

from openptrack_py.tracking.neighbours import count_within
from openptrack_py.tracking.params import TrackerParams
from openptrack_py.tracking.sensor_model import SensorUpdates
from openptrack_py.tracking.state import (
    HISTORY,
    HISTORY_SPACING_S,
    SENSOR_SLOTS,
    DetectionArrays,
    TrackTable,
    sensor_slot,
)

RECENT_WEIGHT = 0.3
"""Weight of a new detection in a track's recent detected position (``recent_xy``)."""
BIRTH_DETECTIONS = 5
"""Detections averaged into where a track started (``TrackTable.birth_xy``)."""


def absorb(
    tb: TrackTable,
    rows: np.ndarray,
    cols: np.ndarray,
    dets: DetectionArrays,
    t: float,
    prior_support: np.ndarray,
    sensor_index: int,
    params: TrackerParams,
) -> None:
    """Bookkeeping of tracks ``rows`` that got detections ``cols`` at time ``t``.

    Height, centroid and confidence averages; keepalive (``last_seen``, ``hits``) by
    confident detections while the track's ``prior_support`` holds; where it is now and
    where it started by its detections; which sensors see it; its position history.
    """
    a = params.height_smoothing
    tb.height[rows] = (1 - a) * tb.height[rows] + a * dets.height[cols]
    tb.z[rows] = (1 - a) * tb.z[rows] + a * dets.z[cols]
    tb.confidence[rows] = 0.8 * tb.confidence[rows] + 0.2 * dets.confidence[cols]
    # Only confident detections keep a track alive (OpenPTrack's "last high-confidence
    # detection"), and a confirmed track only while its support holds: a lost track whose
    # gate has grown wide cannot live on a confident false positive now and then.
    # (A tentative track's evidence is judged by the initiator.)
    confident = dets.confidence[cols] >= params.min_confidence_keepalive
    confident &= ~tb.confirmed[rows] | (prior_support >= params.keepalive_min_support)
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
    other = tb.last_sensor[rows] != sensor_index
    tb.multi_t[rows[other]] = t
    tb.last_sensor[rows] = sensor_index
    # history of posterior positions, at most one entry per spacing interval; the
    # oldest (or an empty) slot is overwritten
    due = rows[t - tb.hist_t[rows].max(axis=1) >= HISTORY_SPACING_S]
    slots = np.argmin(tb.hist_t[due], axis=1)
    tb.hist_t[due, slots] = t
    tb.hist_xy[due, slots] = tb.x[due, 0:2]


def new_rows(
    dets: DetectionArrays,
    new: np.ndarray,
    ids: np.ndarray,
    t: float,
    position_var: np.ndarray,
    sensor_index: int,
    params: TrackerParams,
) -> dict[str, np.ndarray]:
    """Table rows (one array per column) of tentative tracks started by detections ``new``."""
    n = len(new)
    x = np.zeros((n, 4))
    x[:, 0:2] = dets.xy[new]
    cov = np.zeros((n, 4, 4))
    cov[:, 0, 0] = cov[:, 1, 1] = position_var
    cov[:, 2, 2] = cov[:, 3, 3] = params.initial_velocity_sigma_mps**2
    hist_t = np.full((n, HISTORY), -np.inf)
    hist_t[:, 0] = t
    hist_xy = np.zeros((n, HISTORY, 2))
    hist_xy[:, 0] = dets.xy[new]
    hit_t = _first_hit(n, sensor_index, t)
    return {
        "ids": ids,
        "x": x,
        "cov": cov,
        "z": dets.z[new],
        "height": dets.height[new],
        "confidence": dets.confidence[new],
        "first_seen": np.full(n, t),
        "last_seen": np.full(n, t),
        "hits": np.ones(n, dtype=np.int64),
        "confirmed": np.zeros(n, dtype=bool),
        "hist_t": hist_t,
        "hist_xy": hist_xy,
        "support": np.ones(n),
        "birth_xy": dets.xy[new].copy(),
        "recent_xy": dets.xy[new].copy(),
        "birth_n": np.ones(n, dtype=np.int64),
        "last_sensor": np.full(n, sensor_index),
        "multi_t": np.full(n, -np.inf),
        "evidence": np.full(n, params.evidence_per_hit),
        "sensor_hit_t": hit_t,
        "sensor_evidence": np.where(np.isfinite(hit_t), params.evidence_per_hit, 0.0),
        "sensor_support": np.zeros((n, SENSOR_SLOTS)),
    }


def update_support(
    tb: TrackTable,
    hit_rows: np.ndarray,
    expected: np.ndarray,
    sensor_index: int,
    t: float,
    params: TrackerParams,
    hidden: np.ndarray | None = None,
    certain: np.ndarray | None = None,
) -> np.ndarray:
    """Tracks ``expected`` to be seen (and those hit) gain support and evidence if hit.

    Support moves toward hit/miss. Evidence adds the log-likelihood ratio of a hit or of
    a miss (``params.evidence_per_hit`` / ``evidence_per_miss``) for every frame of a
    sensor that has detected the track within ``params.evidence_memory_s``, whatever
    the coverage map says yet: a sensor whose view of the place has been blocked for a
    while (a wall, a cabinet, other people) or cut by the edge of its image says nothing.
    Nor does a frame in which the track is ``hidden`` from the sensor behind another
    person, whether it detected the track or not: which frames count must not depend on
    their outcome, or a static false positive behind people, whose misses would be
    excused and whose hits not, would pass for a person.
    """
    hit = np.zeros(len(tb), dtype=bool)
    hit[hit_rows] = True
    slot = sensor_slot(sensor_index)
    keepalive = tb.support[hit_rows].copy()
    own = tb.sensor_support[hit_rows, slot].copy() if params.keepalive_beside_m > 0 else None
    visible = np.ones(len(tb), dtype=bool) if hidden is None else ~hidden
    expected = (expected | hit) & visible
    tb.support[expected] += params.support_rate * (hit[expected] - tb.support[expected])
    recent = t - tb.sensor_hit_t[:, slot] <= params.evidence_memory_s
    counted = (hit | recent) & visible
    tb.evidence[counted] += np.where(
        hit[counted], params.evidence_per_hit, params.evidence_per_miss
    )
    if params.sensor_evidence:
        _sensor_evidence(tb, hit, counted, slot, params)
    tb.sensor_hit_t[hit, slot] = t
    if own is not None:
        sure = hit
        if certain is not None:
            sure = np.zeros(len(tb), dtype=bool)
            sure[certain] = True
        moved = _sensor_support(tb, hit, sure, expected, slot, params)[hit_rows]
        keepalive[moved] = np.maximum(keepalive[moved], own[moved])
    return keepalive


def _sensor_support(
    tb: TrackTable,
    hit: np.ndarray,
    sure: np.ndarray,
    expected: np.ndarray,
    slot: int,
    params: TrackerParams,
) -> np.ndarray:
    """One sensor's frame moves its own support of confirmed tracks.

    Beside other confirmed tracks (within ``params.keepalive_beside_m``) the frame
    counts only if the sensor detected all of them in it: where it saw everyone
    around, whether it saw this track too says whether it sees this person (a
    neighbour hides them from it, or not). A person's second track, fed by one sensor's
    offset or split view, never gains such support: that sensor's frames that feed it
    did not also detect the person's own track beside it. Nor does a hit that was not
    ``sure`` (its detection could have been another track's, or the track could have
    taken another: a lost track's wide gate among people). Away from others every
    frame counts, so a track the sensor stopped seeing (a false positive that ended,
    a person who left) loses the support it had. Returns the mask of tracks moved
    beside others (where that support may keep a track alive).
    """
    rows = np.flatnonzero(expected & tb.confirmed)
    beside_moved = np.zeros(len(tb), dtype=bool)
    if not len(rows):
        return beside_moved
    r = params.keepalive_beside_m
    beside = count_within(tb.x[rows, 0:2], tb.x[tb.confirmed, 0:2], r) - 1  # not itself
    missed = _undetected_beside(tb, rows, hit, r)
    counts = ((beside == 0) | (missed == 0)) & (sure[rows] | ~hit[rows])
    moved = rows[counts]
    tb.sensor_support[moved, slot] += params.support_rate * (
        hit[moved] - tb.sensor_support[moved, slot]
    )
    beside_moved[rows[counts & (beside > 0)]] = True
    return beside_moved


def _sensor_evidence(
    tb: TrackTable, hit: np.ndarray, counted: np.ndarray, slot: int, params: TrackerParams
) -> None:
    """One sensor's frame adds to its own part of tentative tracks' evidence.

    Beside confirmed tracks (within ``params.co_detection_m``) the frame counts only
    if the sensor detected every one of them in it too: the question there is whether
    the sensor sees one more person than those, and a frame that missed one of them
    cannot tell (its detection of that person may be the one this track took; nor
    does an offset or a split view of a person come as a second blob beside them for
    long).
    """
    rows = np.flatnonzero(counted & ~tb.confirmed)
    if not len(rows):
        return
    if params.co_detection_m > 0:
        rows = rows[_undetected_beside(tb, rows, hit, params.co_detection_m) == 0]
    tb.sensor_evidence[rows, slot] += np.where(
        hit[rows], params.evidence_per_hit, params.evidence_per_miss
    )


def _undetected_beside(tb: TrackTable, rows: np.ndarray, hit: np.ndarray, r: float) -> np.ndarray:
    """How many other confirmed tracks within ``r`` of each of ``rows`` this frame missed."""
    missed = count_within(tb.x[rows, 0:2], tb.x[tb.confirmed & ~hit, 0:2], r)
    return missed - (tb.confirmed[rows] & ~hit[rows])  # not itself


def _first_hit(n: int, sensor_index: int, t: float) -> np.ndarray:
    """``sensor_hit_t`` rows of ``n`` tracks first detected by one sensor at ``t``."""
    rows = np.full((n, SENSOR_SLOTS), -np.inf)
    rows[:, sensor_slot(sensor_index)] = t
    return rows


def damp_unseen(tb: TrackTable, t: float, dt: float, params: TrackerParams) -> None:
    """A person nobody sees is more likely to slow down than to walk on for ever.

    While a track is unseen its velocity decays with time constant
    ``unseen_stop_s`` (its covariance with it), so a track does not coast across the
    room after someone who stopped or turned where no sensor sees them.
    """
    if params.unseen_stop_s <= 0:
        return
    unseen = t - tb.last_seen > params.visibility_timeout_s
    if not unseen.any():
        return
    k = math.exp(-dt / params.unseen_stop_s)
    f = np.diag([1.0, 1.0, k, k])
    tb.x[unseen] = tb.x[unseen] @ f
    tb.cov[unseen] = f @ tb.cov[unseen] @ f


def fold_into(tb: TrackTable, keep: np.ndarray, drop: np.ndarray) -> None:
    """Merge tracks ``drop`` into ``keep`` (pairwise) and remove them.

    The kept track moves to the information-weighted mean of both positions and keeps
    the earliest start, the latest sighting and the stronger evidence.
    """
    ik = np.linalg.inv(tb.cov[keep, 0:2, 0:2])
    idr = np.linalg.inv(tb.cov[drop, 0:2, 0:2])
    fused = np.linalg.solve(ik + idr, ik @ tb.x[keep, 0:2, None] + idr @ tb.x[drop, 0:2, None])[
        ..., 0
    ]
    tb.x[keep, 0:2] = fused
    tb.first_seen[keep] = np.minimum(tb.first_seen[keep], tb.first_seen[drop])
    tb.last_seen[keep] = np.maximum(tb.last_seen[keep], tb.last_seen[drop])
    tb.hits[keep] += tb.hits[drop]
    tb.evidence[keep] = np.maximum(tb.evidence[keep], tb.evidence[drop])
    tb.sensor_hit_t[keep] = np.maximum(tb.sensor_hit_t[keep], tb.sensor_hit_t[drop])
    tb.sensor_evidence[keep] = np.maximum(tb.sensor_evidence[keep], tb.sensor_evidence[drop])
    tb.sensor_support[keep] = np.maximum(tb.sensor_support[keep], tb.sensor_support[drop])
    tb.support[keep] = np.maximum(tb.support[keep], tb.support[drop])
    tb.confidence[keep] = np.maximum(tb.confidence[keep], tb.confidence[drop])
    _remove(tb, drop)


def renumber(tb: TrackTable, rows: np.ndarray, first_id: int, t: float) -> None:
    """Tracks ``rows`` go on as new tracks from ``t``, with ids from ``first_id`` on."""
    tb.ids[rows] = np.arange(first_id, first_id + len(rows), dtype=np.int64)
    tb.first_seen[rows] = t


def take_over(tb: TrackTable, lost: np.ndarray, found: np.ndarray) -> None:
    """Tracks ``found`` take the ids (and start times) of ``lost``, which are removed."""
    tb.ids[found] = tb.ids[lost]
    tb.first_seen[found] = tb.first_seen[lost]
    _remove(tb, lost)


def _remove(tb: TrackTable, rows: np.ndarray) -> None:
    mask = np.ones(len(tb), dtype=bool)
    mask[rows] = False
    tb.keep(mask)


def learnable_updates(
    tb: TrackTable,
    rows: np.ndarray,
    cols: np.ndarray,
    dets: DetectionArrays,
    predicted: np.ndarray,
    pzz: np.ndarray,
    model: np.ndarray,
    gated: np.ndarray,
    t: float,
    sensor_index: int,
    gate: float,
    multi_sensor_s: float = 1.0,
) -> SensorUpdates | None:
    """The updates of one batch that a sensor model may learn from, or ``None``.

    Only settled, unambiguous ones: a confirmed track at least a second old, with one
    detection in its gate, that detection in no other confirmed track's gate. A
    tentative track does not make a pair ambiguous: it is unproven, and where the
    sensors are noisier than configured their own detections of the person start
    tentative tracks beside it, which would otherwise keep the noise from being learned
    (one person walking past three sensors with 0.25 m of noise per axis: 61-69 pairs
    learned per sensor in 12 s, the first noise fit after 10 s). ``predicted``,
    ``pzz`` and ``model`` are per assigned pair: the predicted position, its covariance
    and the configured (unscaled) measurement covariance.
    """
    clear = (
        tb.confirmed[rows]
        & (t - tb.first_seen[rows] >= 1.0)
        & (gated[rows].sum(axis=1) == 1)
        & ((gated[:, cols] & tb.confirmed[:, None]).sum(axis=0) == 1)
    )
    if not clear.any():
        return None
    multi = (t - tb.multi_t[rows] <= multi_sensor_s) | (tb.last_sensor[rows] != sensor_index)
    pzz, model, kept = pzz[clear], model[clear], cols[clear]
    return SensorUpdates(
        sensor_id=dets.sensor_id,
        detected=dets.xy[kept],
        predicted=predicted[clear],
        distance=dets.distance[kept],
        track_var=0.5 * (pzz[:, 0, 0] + pzz[:, 1, 1]),
        model_var=0.5 * (model[:, 0, 0] + model[:, 1, 1]),
        gate=gate,
        multi_sensor=multi[clear],
    )
