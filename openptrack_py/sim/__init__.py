"""Simulation: a world of people, virtual sensors and ground truth, without a camera."""

from openptrack_py.sim.profiles import PROFILE_NAMES, PROFILES, NoiseProfile
from openptrack_py.sim.scenarios import (
    SCENARIO_NAMES,
    Scenario,
    build_scenario,
    describe_scenarios,
)
from openptrack_py.sim.sensors import SENSOR_NOISE, SensorModel, SensorNoise, SensorSpec
from openptrack_py.sim.simulator import DEFAULT_START_TIME, SensorFrame, Simulator, TruthFrame
from openptrack_py.sim.world import Obstacle, PersonSpec, Room, World

__all__ = [
    "DEFAULT_START_TIME",
    "PROFILES",
    "PROFILE_NAMES",
    "SCENARIO_NAMES",
    "SENSOR_NOISE",
    "NoiseProfile",
    "Obstacle",
    "PersonSpec",
    "Room",
    "Scenario",
    "SensorFrame",
    "SensorModel",
    "SensorNoise",
    "SensorSpec",
    "Simulator",
    "TruthFrame",
    "World",
    "build_scenario",
    "describe_scenarios",
]
