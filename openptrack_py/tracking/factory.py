"""Assembling a tracker from its configuration: which role gets which parameters.

:func:`build_tracker` is the one place that reads
:class:`~openptrack_py.config.TrackerConfig`; the tracker and its roles take plain
arguments, so tests and other front ends can compose them directly.
"""

from __future__ import annotations

import math

from scipy.stats import chi2

from openptrack_py.config import TrackerConfig
from openptrack_py.tracking.association import GlobalNearestNeighbour
from openptrack_py.tracking.base import IdentityModel, MeasurementModel
from openptrack_py.tracking.gating import ChiSquareGater
from openptrack_py.tracking.identity import AppearanceIdentity, NullIdentity, load_roster
from openptrack_py.tracking.lifecycle import ConfidenceInitiator, TimeDeleter
from openptrack_py.tracking.measurement import PositionMeasurement, PositionVelocityMeasurement
from openptrack_py.tracking.merging import TrackMerger
from openptrack_py.tracking.motion import ConstantVelocity
from openptrack_py.tracking.params import TrackerParams
from openptrack_py.tracking.sensor_model import OnlineSensorModel
from openptrack_py.tracking.tracker import Tracker
from openptrack_py.tracking.twins import TwinAligner


def build_tracker(config: TrackerConfig | None = None) -> Tracker:
    """Assemble a :class:`Tracker` from a :class:`~openptrack_py.config.TrackerConfig`."""
    cfg = config or TrackerConfig()
    position = PositionMeasurement(cfg.measurement_sigma_m, cfg.measurement_sigma_per_m2)
    measurement: MeasurementModel = position
    if cfg.velocity_in_motion_term:
        measurement = PositionVelocityMeasurement(position, cfg.velocity_sigma_mps)
    still = math.log(1.0 / cfg.confirm_still_error) if cfg.confirm_still_error > 0 else math.inf
    return Tracker(
        motion=ConstantVelocity(cfg.acceleration_variance),
        measurement=measurement,
        gater=ChiSquareGater(cfg.gate_probability, measurement.dim),
        associator=GlobalNearestNeighbour(),
        initiator=ConfidenceInitiator(
            cfg.min_confidence_initialization,
            cfg.detections_to_validate,
            birth_gate=float(chi2.ppf(cfg.birth_gate_probability, measurement.dim)),
            min_age_s=cfg.confirm_min_age_s,
            min_support=cfg.confirm_min_support,
            min_displacement_m=cfg.confirm_min_displacement_m,
            min_separation_m=cfg.birth_min_separation_m,
            still_min_age_s=cfg.confirm_still_min_age_s,
            still_clearance_m=cfg.confirm_still_clearance_m,
            still_per_sensor=cfg.confirm_still_per_sensor,
            one_sensor_min_age_s=cfg.confirm_one_sensor_min_age_s,
            still_evidence=still,
        ),
        deleter=TimeDeleter(cfg.sec_before_fake, cfg.sec_before_old, cfg.tentative_timeout_s),
        sensors=OnlineSensorModel(
            adapt_noise=cfg.adaptive_noise,
            estimate_bias=cfg.estimate_bias,
            scale_bounds=(cfg.noise_scale_min, cfg.noise_scale_max),
            max_bias_m=cfg.max_bias_m,
            calibration_sigma=(cfg.calibration_sigma_m, cfg.calibration_sigma_deg),
            twins=TwinAligner(max_shift_m=3.0 * cfg.max_bias_m) if cfg.align_from_twins else None,
        ),
        merger=TrackMerger(
            cfg.merge_distance_m,
            cfg.merge_after_s,
            cfg.merge_max_speed_difference_mps,
            gate=float(chi2.ppf(cfg.gate_probability, 2)) if cfg.merge_by_noise else None,
            distinct_sensors=cfg.merge_distinct_sensors,
        ),
        identity=build_identity(cfg),
        params=TrackerParams(
            detector_weight=cfg.detector_weight,
            min_confidence_detections=cfg.min_confidence_detections,
            min_confidence_keepalive=cfg.min_confidence_initialization,
            confidence_decay_s=cfg.sec_before_old,
            visibility_timeout_s=cfg.visibility_timeout_s,
            initial_velocity_sigma_mps=cfg.initial_velocity_sigma_mps,
            height_smoothing=cfg.height_smoothing,
            publish_tentative=cfg.publish_tentative,
            publish_unseen_s=cfg.publish_unseen_s,
            publish_min_support=cfg.publish_min_support,
            late_policy=cfg.late_policy,
            max_lateness_s=cfg.max_lateness_s,
            max_replay_steps=cfg.max_replay_steps,
            max_tracks=cfg.max_tracks,
            support_rate=cfg.support_rate,
            keepalive_min_support=cfg.keepalive_min_support,
            occlusion_twin_m=(2.0 * cfg.merge_distance_m if cfg.occlusion_aware_support else 0.0),
            unseen_stop_s=cfg.unseen_stop_s,
            shared_noise_factor=cfg.shared_noise_factor,
            shared_noise_pda=cfg.shared_noise_pda,
            approach_stop_s=cfg.approach_stop_s,
            person_gap_m=cfg.person_gap_m,
            evidence_per_hit=math.log(
                cfg.confirm_still_person_rate / cfg.confirm_still_clutter_rate
            ),
            evidence_per_miss=math.log(
                (1.0 - cfg.confirm_still_person_rate) / (1.0 - cfg.confirm_still_clutter_rate)
            ),
            sensor_evidence=cfg.confirm_still_per_sensor,
            co_detection_m=cfg.confirm_still_clearance_m if cfg.confirm_still_per_sensor else 0.0,
            keepalive_beside_m=cfg.confirm_still_clearance_m if cfg.keepalive_per_sensor else 0.0,
            merge_proof_unambiguous=cfg.merge_proof_unambiguous,
        ),
    )


def build_identity(config: TrackerConfig) -> IdentityModel:
    """The identity role ``config.identity`` asks for, with its roster loaded."""
    cfg = config.identity
    if not cfg.enabled:
        return NullIdentity()
    roster = load_roster(cfg.roster_file) if cfg.roster_file is not None else None
    return AppearanceIdentity(cfg, roster)
