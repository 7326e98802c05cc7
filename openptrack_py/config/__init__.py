"""Typed configuration, loaded from YAML, with ``--set key.path=value`` overrides.

One **network file** describes a whole deployment: the site name, how Zenoh sessions
meet, every sensor (id, type, host, rate, pose or calibration file), the simulator and
each node's settings. Every node reads the same file and uses its own section.

Unknown keys and out-of-range values raise :class:`~openptrack_py.errors.ConfigError`
naming the key path, the allowed values and the value received::

    sensors.0.rat: unknown key; did you mean 'rate_hz'? (allowed: calibration, clock_offset_s, ...)
    sensors.1.rate_hz: must be > 0 (received -5)

The package has one module per section, each a pydantic model on
:class:`~openptrack_py.config.base.StrictModel`: ``zenoh``, ``sensors``, ``sim``,
``detector``, ``tracker``, ``output``, ``recorder``, ``security``, and ``network`` (the
whole file); ``base`` holds what they share and ``loading`` reads files, applies
overrides and turns validation errors into those messages. Everything is importable from here::

    from openptrack_py.config import NetworkConfig, load_network
"""

from openptrack_py.config.base import ENDPOINT_PROTOCOLS, NAME_PATTERN, Name, StrictModel
from openptrack_py.config.detector import (
    HEIGHT_PRESETS,
    BackgroundConfig,
    DetectorConfig,
    GroundConfig,
    HogConfig,
)
from openptrack_py.config.identity import IdentityConfig
from openptrack_py.config.loading import (
    apply_overrides,
    load_config,
    load_network,
    parse_override_value,
    read_yaml,
    to_yaml,
    validate_config,
)
from openptrack_py.config.network import NetworkConfig
from openptrack_py.config.output import (
    OscSinkConfig,
    OutputConfig,
    SmootherConfig,
    UdpSinkConfig,
    WebConfig,
    ZoneSinkConfig,
)
from openptrack_py.config.places import DoorConfig, ZoneConfig
from openptrack_py.config.recorder import RecorderConfig
from openptrack_py.config.security import SecurityConfig
from openptrack_py.config.sensors import Pose, PoseError, SensorConfig, SimLens
from openptrack_py.config.sim import ScenarioName, SimConfig
from openptrack_py.config.tracker import ROBUSTNESS_OFF, TrackerConfig
from openptrack_py.config.zenoh import ZenohConfig

__all__ = [
    "ENDPOINT_PROTOCOLS",
    "HEIGHT_PRESETS",
    "NAME_PATTERN",
    "ROBUSTNESS_OFF",
    "BackgroundConfig",
    "DetectorConfig",
    "DoorConfig",
    "GroundConfig",
    "HogConfig",
    "IdentityConfig",
    "Name",
    "NetworkConfig",
    "OscSinkConfig",
    "OutputConfig",
    "Pose",
    "PoseError",
    "RecorderConfig",
    "ScenarioName",
    "SecurityConfig",
    "SensorConfig",
    "SimConfig",
    "SimLens",
    "SmootherConfig",
    "StrictModel",
    "TrackerConfig",
    "UdpSinkConfig",
    "WebConfig",
    "ZenohConfig",
    "ZoneConfig",
    "ZoneSinkConfig",
    "apply_overrides",
    "load_config",
    "load_network",
    "parse_override_value",
    "read_yaml",
    "to_yaml",
    "validate_config",
]
