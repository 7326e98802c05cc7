"""A whole network file: every section together, checked for consistency."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field, model_validator

from openptrack_py.config.base import Name, StrictModel
from openptrack_py.config.detector import DetectorConfig
from openptrack_py.config.output import OutputConfig
from openptrack_py.config.places import DoorConfig, ZoneConfig
from openptrack_py.config.recorder import RecorderConfig
from openptrack_py.config.security import SecurityConfig
from openptrack_py.config.sensors import SensorConfig
from openptrack_py.config.sim import SimConfig
from openptrack_py.config.tracker import TrackerConfig
from openptrack_py.config.zenoh import ZenohConfig
from openptrack_py.errors import ConfigError

CALIBRATION = "calibration"
"""Name (and identity) of the node that serves the calibration."""
LAUNCHER = "launcher"
"""Name (and identity) of ``openptrack launch``: its hub session and status board."""
OPERATOR = "operator"
"""Default identity of the command-line tools (``config``, ``status``, ``echo``)."""
RECORDER = "record"
SIM = "sim"
TRACKER = "tracker"
RESERVED_NODE_NAMES = (CALIBRATION, LAUNCHER, OPERATOR, RECORDER, SIM, TRACKER)
"""Names of nodes and tools that an output node may not take (its stats, its certificate)."""
DETECTOR_PREFIX = "detector_"


def detector_node_name(sensor_id: str) -> str:
    """Name (and identity) of a sensor's detector node: ``detector_<sensor id>``."""
    return f"{DETECTOR_PREFIX}{sensor_id}"


class NetworkConfig(StrictModel):
    """A whole deployment, as read from one network file.

    Parameters
    ----------
    site : str
        Site name, the second chunk of every key (``opt/<site>/...``).
    zenoh : ZenohConfig
        How sessions meet.
    sensors : list of SensorConfig
        Every sensor; ids must be unique.
    calibration : Path, optional
        The network's calibration file (:mod:`openptrack_py.calibration.files`): the pose
        of every sensor it has an entry for (a sensor's own ``calibration`` wins).
    sim : SimConfig, optional
        Present when some sensors are simulated.
    tracker : TrackerConfig, optional
        Present to run a tracker.
    outputs : list of OutputConfig
        Output nodes; names must be unique.
    recorder : RecorderConfig, optional
        Present to record the run.
    detector : DetectorConfig
        Settings of every detector node (sensor machines, and ``rgbd`` simulation).
    stats_interval_s : float
        How often every node publishes its counters.
    security : SecurityConfig, optional
        Mutual TLS and access control for every session; every Zenoh endpoint must then
        be ``tls/``.
    zones : list of ZoneConfig
        Named areas of the floor (analytics, live zone events); names unique.
    doors : list of DoorConfig
        Named doorways (entries and exits); names unique.
    """

    site: Name = "default"
    zenoh: ZenohConfig = Field(default_factory=ZenohConfig)
    sensors: list[SensorConfig] = Field(default_factory=list)
    calibration: Path | None = None
    sim: SimConfig | None = None
    tracker: TrackerConfig | None = None
    outputs: list[OutputConfig] = Field(default_factory=list)
    recorder: RecorderConfig | None = None
    detector: DetectorConfig = Field(default_factory=DetectorConfig)
    stats_interval_s: float = Field(2.0, gt=0.0, le=3600.0)
    security: SecurityConfig | None = None
    zones: list[ZoneConfig] = Field(default_factory=list)
    doors: list[DoorConfig] = Field(default_factory=list)

    @model_validator(mode="after")
    def _consistent(self) -> NetworkConfig:
        ids = [s.id for s in self.sensors]
        duplicates = sorted({i for i in ids if ids.count(i) > 1})
        if duplicates:
            raise ValueError(f"sensor ids must be unique; repeated: {', '.join(duplicates)}")
        for section, items in (("zones", self.zones), ("doors", self.doors)):
            given = [item.name for item in items]
            again = sorted({n for n in given if given.count(n) > 1})
            if again:
                raise ValueError(f"{section} names must be unique; repeated: {', '.join(again)}")
        names = [o.name for o in self.outputs]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"output names must be unique; repeated: {', '.join(twice)}")
        taken = sorted(
            n for n in names if n in RESERVED_NODE_NAMES or n.startswith(DETECTOR_PREFIX)
        )
        if taken:
            raise ValueError(
                f"output names {', '.join(taken)} are other nodes' names (reserved: "
                f"{', '.join(RESERVED_NODE_NAMES)}, {DETECTOR_PREFIX}<sensor id>)"
            )
        simulated = [s.id for s in self.sensors if s.source == "sim"]
        if self.sim is not None and self.sim.sensor_model == "rgbd":
            if self.sim.use_scenario_sensors:
                raise ValueError(
                    "sim.use_scenario_sensors must be false with sim.sensor_model 'rgbd': "
                    "a detector node renders each of the network's own sim sensors"
                )
            if not simulated:
                raise ValueError(
                    "sim.sensor_model 'rgbd' needs sensors with source 'sim' to render "
                    "(none listed)"
                )
        if self.security is not None:
            if self.zenoh.mode != "peer":
                raise ValueError(
                    "with 'security' zenoh.mode must be 'peer': access control checks the "
                    "certificate of the link a message arrives on, and a router or hub "
                    "relaying for clients would stand for every sender"
                )
            plain = [
                f"{key} ({endpoint})"
                for key, endpoint in self.zenoh.named_endpoints()
                if not endpoint.startswith("tls/")
            ]
            if plain:
                raise ValueError(
                    "with 'security' every Zenoh endpoint must be tls/...; not: "
                    + ", ".join(plain)
                )
        if simulated and self.sim is None:
            raise ValueError(
                f"sensors {', '.join(simulated)} have source 'sim' but there is no 'sim' section"
            )
        return self

    @property
    def calibrated(self) -> bool:
        """Whether the network or any sensor names a calibration file."""
        return self.calibration is not None or any(s.calibration for s in self.sensors)

    def output(self, name: str) -> OutputConfig:
        """Return the output node with this name.

        Raises
        ------
        ConfigError
            If there is none.
        """
        for o in self.outputs:
            if o.name == name:
                return o
        known = ", ".join(o.name for o in self.outputs) or "none"
        raise ConfigError(f"outputs: no output named {name!r} (known: {known})")

    def sensor(self, sensor_id: str) -> SensorConfig:
        """Return the sensor with this id.

        Raises
        ------
        ConfigError
            If no sensor has that id.
        """
        for s in self.sensors:
            if s.id == sensor_id:
                return s
        known = ", ".join(s.id for s in self.sensors) or "none"
        raise ConfigError(f"sensors: no sensor with id {sensor_id!r} (known: {known})")
