"""Tracking: constant-velocity UKF per person, chi-square gate, GNN, track lifecycle.

The tracker composes one object per role (:mod:`~openptrack_py.tracking.base`); the
pipeline puts several sensors' batches in capture order before it
(:mod:`~openptrack_py.tracking.ordering`) and late batches are replayed exactly
(:mod:`~openptrack_py.tracking.replay`).
"""

from openptrack_py.tracking.association import GlobalNearestNeighbour
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
from openptrack_py.tracking.factory import build_tracker
from openptrack_py.tracking.gating import ChiSquareGater
from openptrack_py.tracking.identity import NullIdentity
from openptrack_py.tracking.lifecycle import ConfidenceInitiator, TimeDeleter
from openptrack_py.tracking.measurement import PositionMeasurement, PositionVelocityMeasurement
from openptrack_py.tracking.merging import NoMerging, TrackMerger
from openptrack_py.tracking.motion import ConstantVelocity
from openptrack_py.tracking.ordering import ClockAligner, ReorderBuffer
from openptrack_py.tracking.params import TrackerParams
from openptrack_py.tracking.pipeline import TrackingPipeline
from openptrack_py.tracking.sensor_model import OnlineSensorModel
from openptrack_py.tracking.state import DetectionArrays, TrackTable
from openptrack_py.tracking.static_sensors import StaticSensorModel
from openptrack_py.tracking.tracker import Tracker
from openptrack_py.tracking.ukf import MerweSigmaPoints, UnscentedKalmanFilter

__all__ = [
    "Associator",
    "ChiSquareGater",
    "ClockAligner",
    "ConfidenceInitiator",
    "ConstantVelocity",
    "Deleter",
    "DetectionArrays",
    "Gater",
    "GlobalNearestNeighbour",
    "IdentityModel",
    "Initiator",
    "MeasurementModel",
    "Merger",
    "MerweSigmaPoints",
    "MotionModel",
    "NoMerging",
    "NullIdentity",
    "OnlineSensorModel",
    "PositionMeasurement",
    "PositionVelocityMeasurement",
    "ReorderBuffer",
    "SensorModel",
    "Stateful",
    "StaticSensorModel",
    "TimeDeleter",
    "TrackMerger",
    "TrackTable",
    "Tracker",
    "TrackerParams",
    "TrackingPipeline",
    "UnscentedKalmanFilter",
    "build_tracker",
]
