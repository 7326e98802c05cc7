"""The ``tracker`` section: filter, gate, association, lifecycle and fusion settings."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from openptrack_py.config.base import StrictModel


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
        Associated detections a tentative track needs to become confirmed.
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
    """

    host: str = "localhost"
    gate_probability: float = Field(0.95, ge=0.5, le=0.99999)
    acceleration_variance: float = Field(0.5, gt=0.0, le=1000.0)
    measurement_sigma_m: float = Field(0.08, gt=0.0, le=2.0)
    measurement_sigma_per_m2: float = Field(0.002, ge=0.0, le=0.1)
    velocity_in_motion_term: bool = False
    velocity_sigma_mps: float = Field(0.5, gt=0.0, le=10.0)
    detector_weight: float = Field(-1.0, ge=-10.0, le=0.0)
    min_confidence_detections: float = Field(0.0, ge=0.0, le=1.0)
    min_confidence_initialization: float = Field(0.5, ge=0.0, le=1.0)
    detections_to_validate: int = Field(3, ge=1, le=50)
    sec_before_fake: float = Field(2.4, gt=0.0, le=60.0)
    tentative_timeout_s: float = Field(0.5, gt=0.0, le=60.0)
    sec_before_old: float = Field(3.0, gt=0.0, le=600.0)
    visibility_timeout_s: float = Field(0.25, gt=0.0, le=10.0)
    initial_velocity_sigma_mps: float = Field(1.5, gt=0.0, le=20.0)
    height_smoothing: float = Field(0.1, gt=0.0, le=1.0)
    publish_tentative: bool = False
    publish_unseen_s: float = Field(0.5, ge=0.0, le=600.0)
    reorder_window_s: float = Field(0.05, ge=0.0, le=2.0)
    late_policy: Literal["replay", "drop"] = "replay"
    max_lateness_s: float = Field(1.0, ge=0.0, le=10.0)
    max_replay_steps: int = Field(64, ge=1, le=10_000)
    clock_correction: Literal["arrival", "none"] = "arrival"
    max_tracks: int = Field(1000, ge=1, le=100_000)
