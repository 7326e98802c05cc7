"""The tracker's settings that are not roles, in one validated place.

:class:`TrackerParams` holds what the tracker itself decides with (how confident a
detection must be, when a track is visible or published, the late-batch policy, the
support and keepalive rules...); the roles hold their own. ``TrackerConfig`` (the
network file's ``tracker:`` section) is turned into both by
:func:`~openptrack_py.tracking.factory.build_tracker`.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class TrackerParams:
    """Settings of :class:`~openptrack_py.tracking.tracker.Tracker` that are not roles.

    Parameters
    ----------
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
    occlusion_twin_m : float
        A track hidden from a sensor behind a track it detected is not expected to be
        seen by it, unless it is within this distance of one it detected (see
        :func:`~openptrack_py.tracking.viewpoint.hidden`); 0: every covered track is
        expected.
    unseen_stop_s : float
        Time constant of the velocity decay of unseen tracks (0: none).
    shared_noise_factor : float
        Factor on the noise of a detection that two confirmed tracks could both have
        produced (two people in one blob), so it drags its track less.
    shared_noise_pda : bool
        Widen that noise by the odds that the detection is its track's (probabilistic
        data association), ``shared_noise_factor`` at most; otherwise by the factor.
    approach_stop_s : float
        Time constant of the decay of the approach speed of two confirmed tracks that
        could both have produced one detection (0: none).
    person_gap_m : float
        Least distance between the estimates of two tracks known to be two people (0:
        no constraint).
    evidence_per_hit, evidence_per_miss : float
        What a detection, and a frame that should have seen the track but did not, add
        to its evidence (``TrackTable.evidence``).
    evidence_memory_s : float
        A sensor's frames count toward a track's evidence while it has detected the
        track within this long.
    sensor_evidence : bool
        Also keep each sensor's own part of a tentative track's evidence
        (``TrackTable.sensor_evidence``).
    co_detection_m : float
        Within this distance of confirmed tracks, a sensor's frame counts toward a
        tentative track's own evidence from that sensor only if the sensor detected each
        of them in it too (one blob more than the people tracked there).
    keepalive_beside_m : float
        Within this distance of other confirmed tracks, a confirmed track is also kept
        alive by a sensor's detection while that sensor's own support of it
        (``TrackTable.sensor_support``; there over its frames that detected each of them
        too) is at least ``keepalive_min_support`` (0: never).
    merge_proof_unambiguous : bool
        A sensor frame proves the tracks it updated to be two people (so that they are
        not merged, see :class:`~openptrack_py.tracking.merging.TrackMerger`) only through
        detections that were each alone in their track's gate and in no other track's
        gate; all of them still count as detected together (kept a body's depth apart).
    """

    detector_weight: float = -1.0
    min_confidence_detections: float = 0.0
    min_confidence_keepalive: float = 0.0
    confidence_decay_s: float = 1.0
    visibility_timeout_s: float = 0.25
    initial_velocity_sigma_mps: float = 1.5
    height_smoothing: float = 0.1
    publish_tentative: bool = False
    publish_unseen_s: float = 0.5
    publish_min_support: float = 0.0
    late_policy: str = "replay"
    max_lateness_s: float = 1.0
    max_replay_steps: int = 64
    max_tracks: int = 1000
    support_rate: float = 0.2
    multi_sensor_s: float = 1.0
    keepalive_min_support: float = 0.0
    occlusion_twin_m: float = 0.0
    unseen_stop_s: float = 0.0
    shared_noise_factor: float = 1.0
    shared_noise_pda: bool = False
    approach_stop_s: float = 0.0
    person_gap_m: float = 0.0
    evidence_per_hit: float = 0.0
    evidence_per_miss: float = 0.0
    evidence_memory_s: float = 0.5
    sensor_evidence: bool = False
    co_detection_m: float = 0.0
    keepalive_beside_m: float = 0.0
    merge_proof_unambiguous: bool = True

    @property
    def needs_certain_pairs(self) -> bool:
        """Whether a step must tell which of its pairs motion alone made certain."""
        return self.keepalive_beside_m > 0 or self.merge_proof_unambiguous

    def __post_init__(self) -> None:
        if self.late_policy not in ("replay", "drop"):
            raise ValueError(
                f"TrackerParams: late_policy must be 'replay' or 'drop', got {self.late_policy!r}"
            )
        if not self.confidence_decay_s > 0:
            raise ValueError(
                f"TrackerParams: confidence_decay_s must be > 0, got {self.confidence_decay_s}"
            )
