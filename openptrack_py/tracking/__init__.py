"""Tracking: constant-velocity UKF per person, chi-square gate, GNN, lifecycle, fusion."""

from openptrack_py.tracking.association import GlobalNearestNeighbour
from openptrack_py.tracking.fusion import ClockAligner, ReorderBuffer, TrackingPipeline
from openptrack_py.tracking.gating import ChiSquareGater
from openptrack_py.tracking.lifecycle import ConfidenceInitiator, TimeDeleter
from openptrack_py.tracking.measurement import PositionMeasurement, PositionVelocityMeasurement
from openptrack_py.tracking.motion import ConstantVelocity
from openptrack_py.tracking.tracker import Tracker, build_tracker
from openptrack_py.tracking.ukf import MerweSigmaPoints, UnscentedKalmanFilter

__all__ = [
    "ChiSquareGater",
    "ClockAligner",
    "ConfidenceInitiator",
    "ConstantVelocity",
    "GlobalNearestNeighbour",
    "MerweSigmaPoints",
    "PositionMeasurement",
    "PositionVelocityMeasurement",
    "ReorderBuffer",
    "TimeDeleter",
    "Tracker",
    "TrackingPipeline",
    "UnscentedKalmanFilter",
    "build_tracker",
]
