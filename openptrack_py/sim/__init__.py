"""Simulation: a world of people, virtual sensors and ground truth, without a camera."""

from openptrack_py.sim.scenarios import (
    SCENARIO_NAMES,
    Scenario,
    build_scenario,
    describe_scenarios,
)
from openptrack_py.sim.sensors import SENSOR_TYPES, SensorModel, SensorSpec, SensorType
from openptrack_py.sim.simulator import DEFAULT_START_TIME, SensorFrame, Simulator, TruthFrame
from openptrack_py.sim.world import Obstacle, PersonSpec, Room, World

__all__ = [
    "DEFAULT_START_TIME",
    "SCENARIO_NAMES",
    "SENSOR_TYPES",
    "Obstacle",
    "PersonSpec",
    "Room",
    "Scenario",
    "SensorFrame",
    "SensorModel",
    "SensorSpec",
    "SensorType",
    "Simulator",
    "TruthFrame",
    "World",
    "build_scenario",
    "describe_scenarios",
]
