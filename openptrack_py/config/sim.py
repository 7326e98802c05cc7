"""The ``sim`` section: the simulator node and the scenario it plays."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from openptrack_py.config.base import StrictModel

ScenarioName = Literal[
    "crowd", "distance", "occlusions", "classroom", "installation", "stress", "reentry",
    "uniforms", "overhead", "corridor", "walk",
]  # fmt: skip
"""Named scenarios (built by :mod:`openptrack_py.sim.scenarios`)."""

ProfileName = Literal["ideal", "realistic", "harsh"]
"""Named sensor noise profiles (:data:`openptrack_py.sim.profiles.PROFILES`)."""


class SimConfig(StrictModel):
    """The simulator node: a scenario played in real time on the network's sim sensors.

    Parameters
    ----------
    host : str
        Machine that runs the simulator node.
    scenario : str
        Named scenario; see ``openptrack_py.sim.scenarios``.
    seed : int
        Random seed: the same seed gives the same people, paths and noise.
    duration_s : float, optional
        Stop after this much simulated time (forever if omitted).
    speed : float
        Playback speed relative to real time.
    profile : {"ideal", "realistic", "harsh"}
        How far the simulated detectors are from perfect (``sensor_model: detections``):
        ``realistic`` is calibrated from what real people detectors deliver, ``ideal``
        is the sensor types' noise alone, ``harsh`` a badly calibrated, cluttered room
        (``openptrack_py.sim.profiles``).
    embeddings : bool
        Detections of people facing a sensor within reach carry simulated identity
        embeddings (``face`` and ``face_confidence``; ``openptrack_py.sim.embeddings``):
        a stand-in for a face recogniser (``sensor_model: detections``).
    sensor_model : {"detections", "rgbd"}
        Level of sensor simulation: ``detections`` draws detections directly from the
        ground truth through each sensor's field of view, occlusion and noise model;
        ``rgbd`` renders each sensor's depth and colour images and runs the real
        detector on them (one ``detector`` node per simulated sensor).
    ground_truth_rate_hz : float
        Rate of ground-truth frames on ``opt/<site>/ground_truth``.
    use_scenario_sensors : bool
        Ignore the network's sensors and use the scenario's own placement.
    start_time : float, optional
        UNIX time of the scenario's start, shared by every process that simulates part of
        it (``openptrack launch`` sets it for ``rgbd``); now if omitted.
    """

    host: str = "localhost"
    scenario: ScenarioName = "installation"
    seed: int = Field(0, ge=0, le=2**32 - 1)
    duration_s: float | None = Field(None, gt=0.0)
    speed: float = Field(1.0, gt=0.0, le=100.0)
    profile: ProfileName = "realistic"
    embeddings: bool = False
    sensor_model: Literal["detections", "rgbd"] = "detections"
    ground_truth_rate_hz: float = Field(30.0, gt=0.0, le=240.0)
    use_scenario_sensors: bool = False
    start_time: float | None = Field(None, ge=0.0)
