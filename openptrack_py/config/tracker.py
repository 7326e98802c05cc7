"""The ``tracker`` section: filter, gate, association, lifecycle and fusion settings."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator

from openptrack_py.config.base import Name, StrictModel
from openptrack_py.config.identity import IdentityConfig


class TrackerConfig(StrictModel):
    """The tracker: filter, gate, association, track lifecycle and multi-sensor fusion.

    Every parameter can be changed while the tracker runs
    (``openptrack config tracker key=value``); the change applies before the next step.

    Parameters
    ----------
    host : str
        Machine that runs the tracker node.
    gate_probability : float
        Probability mass of the chi-square gate: a detection can be associated with a
        track when its squared Mahalanobis distance is below
        ``chi2.ppf(gate_probability, dof)``, with ``dof`` the measurement dimension.
    acceleration_variance : float
        Spectral density of the white-noise acceleration of the constant-velocity
        model, m^2/s^3. Larger values follow sharper turns and widen the gate faster.
    measurement_sigma_m : float
        Standard deviation of a detection's position, metres.
    measurement_sigma_per_m2 : float
        Extra standard deviation per squared metre of detection distance (depth noise
        of structured-light sensors grows with the square of the range).
    velocity_in_motion_term : bool
        Also measure velocity, as the displacement of the detection from the track's
        estimate about a second earlier (OpenPTrack's option); the gate then has 4
        degrees of freedom.
    velocity_sigma_mps : float
        Standard deviation of that velocity measurement.
    detector_weight : float
        Weight of the detection's confidence in the association cost (negative: more
        confident detections are preferred).
    min_confidence_detections : float
        Detections below this confidence are ignored.
    min_confidence_initialization : float
        Only detections at least this confident start new tracks.
    detections_to_validate : int
        Confident detections a tentative track needs to become confirmed.
    confirm_min_age_s : float
        Least time from a track's first detection to its confirmation: several sensors
        seeing one blob in the same instant are not yet consistent evidence.
    confirm_min_support : float
        Least share of the recent frames of the sensors that cover a tentative track's
        place that must have detected it (0 disables).
    confirm_min_displacement_m : float
        Least distance a tentative track must have moved from where it started before
        it is confirmed: people walk, while false positives that recur at one place (a
        coat rack, a poster board, a fan) do not (0 disables). A track that has not
        moved is confirmed by steadiness instead (``confirm_still_*``).
    confirm_still_person_rate : float
        How often a depth sensor detects a person standing in its view: the OpenPTrack
        paper's Kinect v2 missed 7.1 % of people in its "Distance" sequence, where
        nobody is hidden.
    confirm_still_clutter_rate : float
        The highest per-frame detection rate of a static false positive that must not be
        confirmed (less than ``confirm_still_person_rate``).
    confirm_still_error : float
        Probability that a static false positive detected at ``confirm_still_clutter_rate``
        is confirmed, per tentative track: a track that has not moved is confirmed when
        a sequential probability ratio test between the two rates, over the frames of
        the sensors that cover its place, reaches ``ln(1 / confirm_still_error)``.
        0: a track must move to be confirmed.
    confirm_still_min_age_s : float
        Least age of a track confirmed by steadiness: transient false positives (a
        reflection, a door swinging, a chair being moved) last a fraction of a second
        and are an artefact of one sensor's view, so two sensors' detections waive it.
    confirm_still_clearance_m : float
        A track this close to a confirmed one must move to be confirmed: a steady blob
        beside a tracked person is more likely that person seen otherwise (a second
        sensor's offset view, a raised arm, a bag) than a second, motionless person.
    confirm_still_per_sensor : bool
        A track that has not moved may also be confirmed by one sensor's steady view of
        it alone (that sensor's own sequential test, at the same error overall), beside
        confirmed tracks too, where only the sensor's frames that detected each of them
        as well count: a person standing still in a group, partly hidden from the other
        sensors, is confirmed by the one that sees them beside their neighbours.
    confirm_one_sensor_min_age_s : float
        Least age of a track confirmed so (by one sensor's view alone): a split of a
        person, or a transient false positive, lasts a fraction of a second (below
        ``sec_before_fake``, or nothing is ever confirmed so).
    birth_min_separation_m : float
        A detection closer than this to a confirmed track never starts a new track: two
        people's centres are never that close (a people detector merges them first).
    birth_gate_probability : float
        A detection within ``chi2.ppf(birth_gate_probability, dof)`` of any track never
        starts a new track (a detection that track could have produced); at least
        ``gate_probability``.
    sec_before_fake : float
        A tentative track not confirmed within this time is deleted.
    tentative_timeout_s : float
        A tentative track without a confident detection for this long is deleted, so the
        ``detections_to_validate`` detections must come close together (clutter rarely
        does; a person in view is detected every frame).
    sec_before_old : float
        A confirmed track without a detection of at least
        ``min_confidence_initialization`` for this long is deleted (low-confidence
        detections update a track but do not keep it alive).
    visibility_timeout_s : float
        A track unseen for longer than this is reported as not visible.
    initial_velocity_sigma_mps : float
        Standard deviation of a new track's unknown velocity.
    height_smoothing : float
        Weight of a new height measurement in the track height's moving average.
    publish_tentative : bool
        Publish tentative tracks too (with ``confirmed: false``).
    publish_unseen_s : float
        Confirmed tracks unseen for longer are kept (so the person gets the same id
        back when seen again before ``sec_before_old``) but not published.
    publish_min_support : float
        Confirmed tracks whose support (see ``support_rate``) has fallen below this are
        kept, with their id, but not published: a track that the sensors covering its
        place have stopped seeing (a person's track left on a static false positive).
    reorder_window_s : float
        How long a batch may wait for batches of other sensors captured earlier; 0
        applies batches in arrival order. Batches are released sooner when every other
        live sensor has already delivered a later frame.
    late_policy : {"replay", "drop"}
        What to do with a batch captured before batches already applied: go back to the
        tracker's state before its capture time and replay it and every later batch
        (exact), or drop it. Both are counted.
    max_lateness_s : float
        How far back replays reach; later batches are dropped.
    max_replay_steps : int
        A late batch that would replay more steps than this is dropped.
    clock_correction : {"arrival", "none"}
        ``arrival``: estimate each sensor's clock offset from the minimum of
        (arrival time - stamp) and align all sensors to their median, so a sensor whose
        clock is off by a constant is corrected within seconds (what remains is the
        difference in network latency). ``none``: trust the stamps.
    max_tracks : int
        Safety limit on simultaneous tracks.
    adaptive_noise : bool
        Estimate each sensor's measurement noise online from the innovations of the
        confirmed tracks it updates (bounded by ``noise_scale_min``/``noise_scale_max`` on
        the configured covariance), so a sensor noisier than configured widens its own
        gate instead of spawning tracks.
    noise_scale_min, noise_scale_max : float
        Bounds of that estimate, as factors on the configured covariance.
    estimate_bias : bool
        Estimate each sensor's constant offset against the fused tracks (where two or
        more sensors see a person) and remove it from its detections.
    max_bias_m : float
        Largest offset estimated.
    calibration_sigma_m, calibration_sigma_deg : float
        How far off each sensor's calibration may be before its misalignment is learned
        (standard deviations: metres per axis, degrees of yaw). Until then a detection
        compared with a track another sensor fed has both sensors' unlearned
        misalignment added to its noise, so sensors that disagree by more than a gate
        still feed one track per person and their misalignment can be learned; 0 trusts
        the calibration. The OpenPTrack paper reports 5-20 cm and 1-3 degrees before
        refinement (0.12 and 2 are its middle); a calibration refined from a walk or a
        checkerboard needs none.
    align_from_twins : bool
        Learn a misalignment larger than an association gate from *twins*: a track fed
        by one sensor alone beside another sensor's (or several sensors') track, the
        two walking together at a steady separation, where that sensor's *share* is low
        (of its tracks at places others see, under half are fed by others too). One
        pair may be two people walking together; a rigid map of the floor that two or
        more distinct pairs agree on is the calibrations' disagreement, and both sides'
        alignments are taught to meet half-way (``tracking/twins.py``). On by default: a
        calibrated sensor's share is about 1, so it is never taught (docs/evaluation.md,
        "Twin tracks").
    merge_distance_m : float
        Two confirmed tracks closer than this, moving alike, both being detected and
        never detected in one sensor frame together, follow one person.
    merge_max_speed_difference_mps : float
        Largest difference of the two tracks' velocities (a crossing differs by twice a
        walking speed).
    merge_by_noise : bool
        Widen ``merge_distance_m`` and ``merge_max_speed_difference_mps`` with the
        detections' learned noise: two tracks of one person fed by noisy detections
        drift further apart, so they count as close while a detection of either would
        fall within the other's association gate (``gate_probability``), and as moving
        alike while their velocities differ by no more than their uncertainty allows.
    merge_after_s : float
        How long they must stay so before they are merged into the older one (0
        disables merging).
    merge_distinct_sensors : int
        Two tracks detected apart in one sensor frame are two people, but one sensor's
        frames are not enough where others see the place: a detector splits one person
        into two blobs now and then, each sensor in its own view. Where this many
        sensors have detected both tracks in the last second, this many must each have
        seen them apart in the last 5 s (where fewer have, each of them must); 1 (the
        default): any one sensor's frame. 2 removed most duplicates on the development
        scenes but lost identities in dense ones (docs/evaluation.md). Nothing is
        recorded with ``merge_after_s`` 0.
    merge_proof_unambiguous : bool
        A sensor frame proves two tracks to be two people (so that they are never
        merged) only through detections that were each alone in their track's
        association gate and in no other track's gate; the tracks it detected together
        are still kept a body's depth apart (``person_gap_m``; with
        ``merge_distinct_sensors`` 1, the default: with more, only that rule's proof
        keeps tracks apart). Where detections are noisy, gates overlap and a person's
        second track (started before the noise was learned, or by a burst of outliers)
        takes a neighbour's or a stray detection in the same frame as the person's own:
        by the rule without this option that frame proves two people for 5 s, renewed
        while the noise lasts, and the second track is never merged. On by default
        (docs/evaluation.md, "At four times the noise"); off, any frame that detected
        both tracks proves two people.
    keepalive_min_support : float
        A confident detection keeps a track alive only while the track's support (before
        that detection) is at least this: a lost track whose gate has grown wide, or a
        track left on a static false positive, cannot live on a confident false
        detection now and then, while a person seen again after an occlusion regains
        support within a few frames.
    keepalive_per_sensor : bool
        Beside other confirmed tracks (within ``confirm_still_clearance_m``), a
        confident detection also keeps a track alive while the detecting sensor's own
        support of it holds (``keepalive_min_support``), counted there over that
        sensor's frames in which it detected each of those tracks too (away from
        others, over every frame the sensor covers the track): a child standing beside
        another, seen well by the one sensor the neighbour does not hide them from,
        keeps their track although the sensors the neighbour hides them from pull the
        track's support down. A second track on one person's offset or split view
        never gains such support: in the frames that feed it the sensor did not detect
        the person's own track too. Nor does a detection that could have been another
        track's (in another's gate, or not alone in its own): where the sensors are
        noisy or a lost track's gate is wide, the rule steps aside. Off by default
        (docs/evaluation.md).
    occlusion_aware_support : bool
        A sensor's frames in which a track is hidden behind a person it detected (on the
        line of sight from where the ranges of its detections place it, below that
        person's head) say nothing of the track's support and evidence, so a person
        hidden in a crowd keeps their track; except near a detected person (within twice
        ``merge_distance_m``), where the track may be that person's second one.
    unseen_stop_s : float
        While a track is unseen its velocity decays with this time constant: people
        stop and turn, so a track does not coast on across the room after someone who
        stopped where no sensor sees them (0: constant velocity throughout).
    shared_noise_factor : float
        A detection that two confirmed tracks could both have produced (two people
        standing close come out of a detector as one blob) updates its track with this
        many times its noise, so the track is not dragged onto the other person's course
        (1: no difference).
    shared_noise_pda : bool
        Widen that noise by how likely the detection is to be another track's instead
        of always by ``shared_noise_factor`` (probabilistic data association, Bar-Shalom
        and Tse 1975; the factor becomes the largest widening): a detection exactly
        between two tracks counts half, one plainly its own track's counts whole. Under
        noisy detections in a crowd, almost every detection is within two tracks' gates,
        and a fixed factor leaves every track nearly without updates.
    approach_stop_s : float
        Two confirmed tracks that could both have produced one detection belong to
        people close together; while they are on a collision course, the speed at which
        they approach each other decays with this time constant. People about to meet
        slow down and step aside (the social force model of pedestrian motion, Helbing
        and Molnar, 1995); a constant-velocity track coasting through the blob of two
        people comes out on the far side with the other person. 0 (the default): no
        slowing. 0.3 raised IDF1 on ``crowd`` and ``classroom`` but lowered it on
        ``installation`` and added duplicates (docs/evaluation.md): not on by default yet.
    person_gap_m : float
        Least distance between the centres of two people: a body's depth (adults' chest
        depth is 0.2-0.3 m in anthropometric surveys, children's less). Two tracks known
        to be two people (seen apart in the last 5 s, as merging records,
        ``merge_distinct_sensors``; nothing is known with ``merge_after_s`` 0) are never
        estimated closer: their estimates are pushed apart along the line between them,
        each by its share of their uncertainty (a Kalman estimate projected onto the
        constraint). A track coasting through the blob of two people then pushes the
        other ahead instead of passing through it and taking its place. 0: no
        constraint.
    support_rate : float
        Weight of one expected sensor frame in a track's support (the exponential
        average of detected / expected frames).
    frame_id : str or None
        The frame tracked; batches in another are refused (``wrong_frame``). ``None``:
        ``world``, unless the network has a single sensor without a pose (then that
        sensor's own floor frame, named by its id).
    discover_sensors : bool
        Track sensors the network file does not list (otherwise their batches are
        counted as ``unknown_sensor`` and ignored; a network that lists no sensor
        discovers them all); a discovered sensor is forgotten once silent for
        ``sensor_forget_s``.
    sensor_forget_s : float
        See ``discover_sensors``.
    max_clock_offset_s : float
        A sensor's first batch is taken only if stamped within this of its arrival.
    max_clock_jump_s : float
        A batch whose stamp disagrees with its sensor's clock (the median of arrival
        minus stamp over its recent batches) by more is refused (``bad_stamp``): one
        batch stamped far in the future or past never moves the clock.
    state_dir : Path or None
        Where the tracker node keeps its checkpoint (``tracker-<site>.ckpt``): its
        tracks, id counter and learned state, written every ``checkpoint_interval_s``,
        so that after a crash or restart the same people keep their ids and no id is
        ever given to a different person. ``None``: no checkpoint (ids start again at 1
        after a restart).
    checkpoint_interval_s : float
        See ``state_dir``.
    resume_within_s : float
        A checkpoint at most this old resumes its tracks; an older one only the ids.
    identity : IdentityConfig
        Appearance in association, re-identification and named people (off by
        default: ``identity.enabled=true``).
    max_latency_s : float
        Load shedding: a batch that waited longer than this before the tracker could
        take it is dropped (``shed``), so latency stays bounded when the tracker falls
        behind (newest wins).
    """

    host: str = "localhost"
    gate_probability: float = Field(0.99, ge=0.5, le=0.99999)
    acceleration_variance: float = Field(0.5, gt=0.0, le=1000.0)
    measurement_sigma_m: float = Field(0.08, gt=0.0, le=2.0)
    measurement_sigma_per_m2: float = Field(0.002, ge=0.0, le=0.1)
    velocity_in_motion_term: bool = False
    velocity_sigma_mps: float = Field(0.5, gt=0.0, le=10.0)
    detector_weight: float = Field(-1.0, ge=-10.0, le=0.0)
    min_confidence_detections: float = Field(0.0, ge=0.0, le=1.0)
    min_confidence_initialization: float = Field(0.5, ge=0.0, le=1.0)
    detections_to_validate: int = Field(3, ge=1, le=50)
    confirm_min_age_s: float = Field(0.2, ge=0.0, le=60.0)
    confirm_min_support: float = Field(0.5, ge=0.0, le=1.0)
    confirm_min_displacement_m: float = Field(0.5, ge=0.0, le=10.0)
    confirm_still_person_rate: float = Field(0.9, gt=0.0, lt=1.0)
    confirm_still_clutter_rate: float = Field(0.5, gt=0.0, lt=1.0)
    confirm_still_error: float = Field(1e-3, ge=0.0, lt=1.0)
    confirm_still_min_age_s: float = Field(1.0, ge=0.0, le=60.0)
    confirm_still_clearance_m: float = Field(1.0, ge=0.0, le=10.0)
    confirm_still_per_sensor: bool = False
    confirm_one_sensor_min_age_s: float = Field(2.0, ge=0.0, le=60.0)
    birth_gate_probability: float = Field(0.9999, ge=0.5, le=0.999999)
    birth_min_separation_m: float = Field(0.4, ge=0.0, le=2.0)
    sec_before_fake: float = Field(2.4, gt=0.0, le=60.0)
    tentative_timeout_s: float = Field(0.5, gt=0.0, le=60.0)
    sec_before_old: float = Field(3.0, gt=0.0, le=600.0)
    visibility_timeout_s: float = Field(0.25, gt=0.0, le=10.0)
    initial_velocity_sigma_mps: float = Field(1.5, gt=0.0, le=20.0)
    height_smoothing: float = Field(0.1, gt=0.0, le=1.0)
    publish_tentative: bool = False
    publish_unseen_s: float = Field(0.5, ge=0.0, le=600.0)
    publish_min_support: float = Field(0.0, ge=0.0, le=1.0)
    reorder_window_s: float = Field(0.05, ge=0.0, le=2.0)
    late_policy: Literal["replay", "drop"] = "replay"
    max_lateness_s: float = Field(1.0, ge=0.0, le=10.0)
    max_replay_steps: int = Field(64, ge=1, le=10_000)
    clock_correction: Literal["arrival", "none"] = "arrival"
    max_tracks: int = Field(1000, ge=1, le=100_000)
    adaptive_noise: bool = True
    noise_scale_min: float = Field(0.25, gt=0.0, le=1.0)
    noise_scale_max: float = Field(25.0, ge=1.0, le=400.0)
    estimate_bias: bool = True
    max_bias_m: float = Field(0.5, ge=0.0, le=5.0)
    calibration_sigma_m: float = Field(0.0, ge=0.0, le=2.0)
    calibration_sigma_deg: float = Field(0.0, ge=0.0, le=20.0)
    align_from_twins: bool = True
    merge_distance_m: float = Field(0.45, ge=0.0, le=2.0)
    merge_after_s: float = Field(0.5, ge=0.0, le=60.0)
    merge_max_speed_difference_mps: float = Field(1.0, gt=0.0, le=10.0)
    merge_by_noise: bool = True
    merge_distinct_sensors: int = Field(1, ge=1, le=16)
    merge_proof_unambiguous: bool = True
    support_rate: float = Field(0.1, gt=0.0, le=1.0)
    keepalive_min_support: float = Field(0.35, ge=0.0, le=1.0)
    keepalive_per_sensor: bool = False
    occlusion_aware_support: bool = False
    unseen_stop_s: float = Field(1.0, ge=0.0, le=60.0)
    shared_noise_factor: float = Field(10.0, ge=1.0, le=100.0)
    shared_noise_pda: bool = True
    approach_stop_s: float = Field(0.0, ge=0.0, le=60.0)
    person_gap_m: float = Field(0.2, ge=0.0, le=1.0)
    frame_id: Name | None = None
    discover_sensors: bool = False
    sensor_forget_s: float = Field(30.0, gt=0.0, le=86400.0)
    max_clock_offset_s: float = Field(3600.0, gt=0.0, le=1e9)
    max_clock_jump_s: float = Field(1.0, gt=0.0, le=3600.0)
    state_dir: Path | None = None
    checkpoint_interval_s: float = Field(1.0, gt=0.0, le=3600.0)
    resume_within_s: float = Field(30.0, ge=0.0, le=86400.0)
    max_latency_s: float = Field(0.25, gt=0.0, le=60.0)
    identity: IdentityConfig = Field(default_factory=IdentityConfig)

    @model_validator(mode="after")
    def _birth_gate_outside_gate(self) -> TrackerConfig:
        if self.birth_gate_probability < self.gate_probability:
            raise ValueError(
                f"birth_gate_probability ({self.birth_gate_probability}) must be at least "
                f"gate_probability ({self.gate_probability})"
            )
        if self.confirm_still_clutter_rate >= self.confirm_still_person_rate:
            raise ValueError(
                f"confirm_still_clutter_rate ({self.confirm_still_clutter_rate}) must be less "
                f"than confirm_still_person_rate ({self.confirm_still_person_rate})"
            )
        late = self.confirm_one_sensor_min_age_s >= self.sec_before_fake
        if self.confirm_still_per_sensor and late:
            raise ValueError(
                f"confirm_one_sensor_min_age_s ({self.confirm_one_sensor_min_age_s}) must be "
                f"less than sec_before_fake ({self.sec_before_fake}): a tentative track is "
                f"deleted before one sensor could confirm it"
            )
        return self


ROBUSTNESS_OFF: dict[str, object] = {
    "adaptive_noise": False,
    "estimate_bias": False,
    "birth_gate_probability": 0.99,
    "birth_min_separation_m": 0.0,
    "confirm_min_age_s": 0.0,
    "confirm_min_support": 0.0,
    "confirm_min_displacement_m": 0.0,
    "merge_after_s": 0.0,
    "keepalive_min_support": 0.0,
    "occlusion_aware_support": False,
    "unseen_stop_s": 0.0,
    "shared_noise_factor": 1.0,
    "approach_stop_s": 0.0,
    "person_gap_m": 0.0,
}
"""``TrackerConfig`` settings that turn off every mechanism of robust track management
(learned sensor noise and alignment, the birth gate and least separation, confirmation on
evidence, merging, support-based keepalive, slowing unseen tracks, weak updates from
shared blobs): the plain tracker, for comparisons (``TrackerConfig(**ROBUSTNESS_OFF)``)."""
