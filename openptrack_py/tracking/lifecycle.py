"""Which detections start tracks, when tracks are confirmed, and when they are deleted.

Confirmation asks for *consistent evidence*, not a count of anything:

* **birth**: a confident detection starts a tentative track only if it lies outside the
  *birth gate* of every track, a wider chi-square gate than association's, and no closer
  to a confirmed track than two people can stand: a detection that an existing track
  could have produced (a noisy detection of a tracked person, a second sensor's view of
  them, offset by its calibration) never starts a second track;
* **hits over time**: ``detections_to_validate`` confident detections, spread over at
  least ``min_age_s``, so that three sensors seeing one blob in the same instant are not
  enough;
* **support**: most of the recent frames of the sensors that cover the track's place
  detected it (``TrackTable.support``), so a blob one of three overlapping sensors
  reports now and then is not a person;
* **displacement**: the track has moved at least ``min_displacement_m`` from where it
  started. People walk; a coat rack, a poster board or a fan that the detector takes
  for a person recurs at one place and never does, and is never confirmed;
* **or, for a track that has not moved, steadiness**: a person standing in view is
  detected in nearly every frame of the sensors that cover the place, while what a
  detector mistakes for a person it mistakes now and then (a view angle, a shadow, a
  fan turning). Wald's sequential probability ratio test decides between the two: each
  frame that should have seen the track adds ``ln(p1 / p0)`` to its evidence when it
  detected it and ``ln((1 - p1) / (1 - p0))`` when it did not (``p1`` the detection
  rate of a person in view, ``p0`` the highest of a static false positive), and the
  track is confirmed when the evidence reaches ``ln(1 / alpha)``: a static false
  positive detected at rate ``p0`` is confirmed with probability at most ``alpha``,
  a steadily detected person within a second or so. (An object a detector takes for a
  person as often as a person is a person to any tracker until it never moves.)
  Transient false positives are detected in every frame while they last (a fraction
  of a second, in one sensor's view), so steadiness alone also needs ``still_min_age_s``
  unless two sensors have detected the track, and a track beside a confirmed one (that
  person seen otherwise, more likely than a second one standing motionless) must move.
  With ``still_per_sensor`` each sensor's frames are also a test of their own, so one
  sensor's steady view confirms a person the others barely see (a child in a group,
  hidden from two of three sensors by a neighbour); beside confirmed tracks that test
  counts only the frames in which the sensor detected each of them too (one blob more
  than the people tracked there), which a second sensor's offset view or a split of
  one person does not give for long.
  A track that continues a lost person who
  was walking (they reappear from behind a
  pillar within walking reach) needs neither.

Deletion: a tentative track goes ``sec_before_fake`` after its first detection or
``tentative_timeout_s`` without a confident detection; a confirmed track goes
``sec_before_old`` without one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from openptrack_py.tracking.neighbours import nearest_distance
from openptrack_py.tracking.state import DetectionArrays, TrackTable


@dataclass(frozen=True)
class ConfidenceInitiator:
    """Start tentative tracks from confident, unexplained detections; confirm on evidence.

    Parameters
    ----------
    min_confidence : float
        Least confidence of a detection that starts a track.
    detections_to_validate : int
        Confident detections (the first included) needed for confirmation.
    birth_gate : float
        A detection whose squared Mahalanobis distance to some track is at most this
        never starts a track; the default is the 2-D chi-square gate at 0.95 (the
        association gate, OpenPTrack's rule).
    min_age_s : float
        Least time from a track's first detection to its confirmation.
    min_support : float
        Least :attr:`TrackTable.support` at confirmation.
    min_displacement_m : float
        Least distance from where the track started to where it is at confirmation.
    min_separation_m : float
        A detection closer than this to a confirmed track never starts a track: two
        people's centres are never that close (the detector merges them first), so it
        is that person, seen by another sensor or off-centre.
    still_evidence : float
        Evidence (``TrackTable.evidence``) that confirms a track which has not moved
        ``min_displacement_m`` (infinite: only a track that moved is confirmed).
    still_min_age_s : float
        Least age of a track confirmed by steadiness unless two sensors have detected
        it: transient false positives (a reflection, a door swinging, a chair being
        moved) last a fraction of a second, are detected in every frame while they do,
        and are an artefact of one sensor's view.
    still_clearance_m : float
        A track closer than this to a confirmed one is not confirmed by steadiness: a
        steady blob beside a tracked person is more likely that person seen otherwise (a
        second sensor's offset view, a raised arm, a bag) than a second person standing
        motionless.
    still_per_sensor : bool
        A track that has not moved is also confirmed when one sensor's own evidence
        (``TrackTable.sensor_evidence``) reaches ``still_evidence`` plus the log of the
        number of sensors that detected it (each sensor a test of its own, at the same
        error overall), after ``one_sensor_min_age_s``, beside confirmed tracks too: there
        that evidence counts only the sensor's frames that detected each of them as
        well (one blob more than the people tracked there), so a person partly hidden
        from the other sensors, standing half a metre from a neighbour, is confirmed by
        the sensor that sees both of them.
    one_sensor_min_age_s : float
        Least age of a track confirmed by one sensor's steadiness: what one sensor
        alone reports steadily for a moment may be a split of a person beside them or a
        transient false positive, which last a fraction of a second.
    """

    min_confidence: float
    detections_to_validate: int
    birth_gate: float = 5.991464547107979  # chi2.ppf(0.95, 2)
    min_age_s: float = 0.0
    min_support: float = 0.0
    min_displacement_m: float = 0.0
    min_separation_m: float = 0.0
    still_evidence: float = float("inf")
    still_min_age_s: float = 0.0
    still_clearance_m: float = 0.0
    still_per_sensor: bool = False
    one_sensor_min_age_s: float = 0.0

    def initiate(
        self,
        dets: DetectionArrays,
        assigned: np.ndarray,
        d2: np.ndarray,
        table: TrackTable | None = None,
    ) -> np.ndarray:
        """Indices of the detections that start new tracks.

        ``d2 (n_tracks, n_detections)`` are the squared Mahalanobis distances of every
        pair under the tracks' predicted innovation covariances; ``table`` the tracks
        (for the least separation from a confirmed one).
        """
        explained = (d2 <= self.birth_gate).any(axis=0) if len(d2) else np.zeros(len(dets), bool)
        if self.min_separation_m > 0 and table is not None and table.confirmed.any():
            near = nearest_distance(dets.xy, table.x[table.confirmed, 0:2])
            explained |= near < self.min_separation_m
        confident = dets.confidence >= self.min_confidence
        return np.flatnonzero(~assigned & ~explained & confident)

    def confirm(
        self, table: TrackTable, t: float, continuing: np.ndarray | None = None
    ) -> np.ndarray:
        """Confirmation flags after the step at ``t``.

        Tracks marked ``continuing`` (a lost person who was walking, seen again) need
        not have moved.
        """
        ready = table.hits >= self.detections_to_validate
        if self.min_age_s > 0:
            ready &= t - table.first_seen >= self.min_age_s
        if self.min_support > 0:
            ready &= table.support >= self.min_support
        if self.min_displacement_m > 0:
            # measured on the detections, not the filter (which drifts while unseen)
            moved = np.hypot(*(table.recent_xy - table.birth_xy).T) >= self.min_displacement_m
            seen_by = np.isfinite(table.sensor_hit_t).sum(axis=1)
            two_sensors = seen_by >= 2
            lasting = (t - table.first_seen >= self.still_min_age_s) | two_sensors
            steady = (table.evidence >= self.still_evidence) & lasting
            steady &= ~table.confirmed
            if self.still_clearance_m > 0 and steady.any() and table.confirmed.any():
                rows = np.flatnonzero(steady)
                near = nearest_distance(table.x[rows, 0:2], table.x[table.confirmed, 0:2])
                steady[rows] = near >= self.still_clearance_m
            if self.still_per_sensor:
                steady |= self._steady_to_one_sensor(table, t, seen_by)
            moved |= steady
            if continuing is not None:
                moved |= continuing
            ready &= moved
        return table.confirmed | ready

    def _steady_to_one_sensor(
        self, table: TrackTable, t: float, seen_by: np.ndarray
    ) -> np.ndarray:
        """Tentative tracks one sensor alone has seen steadily (see ``still_per_sensor``).

        ``seen_by``: how many sensors have detected each track.
        """
        need = self.still_evidence + np.log(np.maximum(seen_by, 1))
        steady = table.sensor_evidence.max(axis=1, initial=-np.inf) >= need
        return steady & ~table.confirmed & (t - table.first_seen >= self.one_sensor_min_age_s)


@dataclass(frozen=True)
class TimeDeleter:
    """Delete tracks that are stale.

    Parameters
    ----------
    sec_before_fake : float
        A tentative track still unconfirmed this long after its first detection goes.
    sec_before_old : float
        A confirmed track unseen this long goes.
    tentative_timeout_s : float
        A tentative track unseen this long goes: the detections that confirm a track must
        come close together, as a real person's do (a sensor sees them every frame),
        not scattered like clutter.
    """

    sec_before_fake: float
    sec_before_old: float
    tentative_timeout_s: float = float("inf")

    def delete(self, table: TrackTable, t: float) -> np.ndarray:
        """Mask of tracks to delete at time ``t``."""
        confirmed = table.confirmed
        fake = ~confirmed & (
            (t - table.first_seen >= self.sec_before_fake)
            | (t - table.last_seen >= self.tentative_timeout_s)
        )
        old = confirmed & (t - table.last_seen >= self.sec_before_old)
        return fake | old
