"""The one table of sensor facts: what each supported depth sensor type is.

Every layer reads its per-type numbers here: the config validates type names against
:data:`SensorTypeName` and fills detector defaults, the detector picks the image its HOG
check reads, the simulator and renderer take image size, field of view and range, the web
view draws each sensor's reach. The simulator's noise model per type is not a fact of the
sensor and lives with the simulator (:data:`openptrack_py.sim.sensors.SENSOR_NOISE`).

Live devices that are not one of these types but whose nominal optics a source needs
(the Azure Kinect) have a :class:`DeviceFacts` entry.
"""

from __future__ import annotations

import math
import typing
from dataclasses import dataclass
from typing import Literal

SensorTypeName = Literal["kinect1", "kinect2", "realsense", "sr4500"]
"""Sensor type names as written in network files."""

SENSOR_TYPE_NAMES: tuple[SensorTypeName, ...] = typing.get_args(SensorTypeName)
"""The same names, in table order."""


CROWD_DENSITY_PER_M2 = 2.0
"""People per square metre in a dense crowd (Fruin's densest level of service begins
near 2 per square metre)."""


@dataclass(frozen=True)
class SensorType:
    """Nominal facts of one kind of depth sensor.

    Parameters
    ----------
    name : str
        Type name as used in network files.
    width, height : int
        Depth image size, pixels.
    hfov_deg, vfov_deg : float
        Horizontal and vertical field of view, degrees.
    min_range_m, max_range_m : float
        Depth range, metres.
    reliable_range_m : float
        Range within which people are reliably detected, metres: the simulator's misses
        grow beyond it and the web view draws it as the sensor's reach.
    rate_hz : float
        Nominal frame rate.
    detector_max_distance_m : float
        The detector's default depth limit, metres: OpenPTrack's values (Kinect v1 5 m,
        Kinect v2 10 m, SR4500 8 m) and, for RealSense, where its stereo noise (about
        6 cm at 7 m) still leaves a head distinguishable from shoulders.
    detector_sampling_factor : int
        The detector's default pixel sampling step (about 50-80 thousand points per
        frame): 1 for low-resolution images, 2 above.
    detector_min_points : int
        The detector's default fewest points of a person (scaled with resolution).
    time_of_flight : bool
        Depth by time of flight (the HOG check then reads the infrared image) rather
        than by structured light or stereo (it reads the colour image).
    live_input : str or None
        Source opened for a ``camera`` sensor of this type that names no ``input``.
    """

    name: SensorTypeName
    width: int
    height: int
    hfov_deg: float
    vfov_deg: float
    min_range_m: float
    max_range_m: float
    reliable_range_m: float
    rate_hz: float
    detector_max_distance_m: float
    detector_sampling_factor: int
    detector_min_points: int
    time_of_flight: bool
    live_input: str | None = None

    @property
    def max_people_in_view(self) -> int:
        """Most people the sensor can see at once (a bound for admission control).

        Its view within the reliable range at a dense crowd's
        :data:`CROWD_DENSITY_PER_M2`, at least ten.
        """
        area = 0.5 * self.reliable_range_m**2 * math.radians(self.hfov_deg)
        return max(10, math.ceil(area * CROWD_DENSITY_PER_M2))

    @property
    def intrinsics(self) -> tuple[float, float, float, float]:
        """Pinhole ``(fx, fy, cx, cy)`` of the depth image."""
        fx = (self.width / 2) / math.tan(math.radians(self.hfov_deg) / 2)
        fy = (self.height / 2) / math.tan(math.radians(self.vfov_deg) / 2)
        return fx, fy, (self.width - 1) / 2, (self.height - 1) / 2


SENSOR_TYPES: dict[str, SensorType] = {
    "kinect1": SensorType(
        name="kinect1", width=320, height=240, hfov_deg=57.0, vfov_deg=43.0,
        min_range_m=0.8, max_range_m=8.0, reliable_range_m=4.5, rate_hz=30.0,
        detector_max_distance_m=5.0, detector_sampling_factor=1, detector_min_points=12,
        time_of_flight=False,
    ),
    "kinect2": SensorType(
        name="kinect2", width=512, height=424, hfov_deg=70.6, vfov_deg=60.0,
        min_range_m=0.5, max_range_m=10.0, reliable_range_m=8.0, rate_hz=30.0,
        detector_max_distance_m=10.0, detector_sampling_factor=2, detector_min_points=20,
        time_of_flight=True,
    ),
    "realsense": SensorType(
        name="realsense", width=640, height=480, hfov_deg=87.0, vfov_deg=58.0,
        min_range_m=0.3, max_range_m=10.0, reliable_range_m=6.0, rate_hz=30.0,
        detector_max_distance_m=7.0, detector_sampling_factor=2, detector_min_points=20,
        time_of_flight=False, live_input="realsense",
    ),
    "sr4500": SensorType(
        name="sr4500", width=176, height=144, hfov_deg=69.0, vfov_deg=55.0,
        min_range_m=0.4, max_range_m=9.0, reliable_range_m=7.0, rate_hz=13.0,
        detector_max_distance_m=8.0, detector_sampling_factor=1, detector_min_points=8,
        time_of_flight=True,
    ),
}  # fmt: skip
"""Every sensor type by name, in the order of :data:`SENSOR_TYPE_NAMES`."""


@dataclass(frozen=True)
class DeviceFacts:
    """Nominal optics of a live device whose intrinsics the driver may not report.

    Parameters
    ----------
    name : str
        Device name as written in a source spec.
    hfov_deg : float
        Horizontal field of view, degrees (square pixels are assumed).
    """

    name: str
    hfov_deg: float

    def intrinsics_at(self, width: int, height: int) -> tuple[float, float, float, float]:
        """Pinhole ``(fx, fy, cx, cy)`` at an image size, principal point at the centre."""
        fx = (width / 2) / math.tan(math.radians(self.hfov_deg) / 2)
        return fx, fx, (width - 1) / 2, (height - 1) / 2


AZURE_KINECT = DeviceFacts(name="azure-kinect", hfov_deg=90.0)
"""The Azure Kinect's colour camera: 90 degrees across at every resolution."""
