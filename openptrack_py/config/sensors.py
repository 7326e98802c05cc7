"""The ``sensors`` section: each depth sensor's type, host, source and pose."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator

from openptrack_py.config.base import Name, StrictModel
from openptrack_py.sensor_types import SensorTypeName


class Pose(StrictModel):
    """Where a sensor stands and where it looks, in the world frame.

    Parameters
    ----------
    x, y : float
        Position on the floor, metres.
    z : float
        Height of the sensor's optical centre above the floor, metres.
    yaw_deg : float
        Heading of the optical axis, degrees counter-clockwise from +x.
    pitch_deg : float
        Downward tilt of the optical axis, degrees (0 = horizontal, 90 = straight down).
    roll_deg : float
        Rotation about the optical axis, degrees.
    """

    x: float = 0.0
    y: float = 0.0
    z: float = Field(2.5, ge=0.0, le=30.0)
    yaw_deg: float = Field(0.0, ge=-360.0, le=360.0)
    pitch_deg: float = Field(20.0, ge=-90.0, le=90.0)
    roll_deg: float = Field(0.0, ge=-180.0, le=180.0)


class PoseError(StrictModel):
    """Simulated calibration error: the pose the sensor believes minus its true pose."""

    dx: float = Field(0.0, ge=-5.0, le=5.0)
    dy: float = Field(0.0, ge=-5.0, le=5.0)
    dyaw_deg: float = Field(0.0, ge=-45.0, le=45.0)

    def believed(self, pose: Pose) -> Pose:
        """The pose a sensor truly at ``pose`` believes it has."""
        return pose.model_copy(
            update={
                "x": pose.x + self.dx,
                "y": pose.y + self.dy,
                "yaw_deg": pose.yaw_deg + self.dyaw_deg,
            }
        )


class SimLens(StrictModel):
    """A simulated unit's lens, and the lens its driver reports with each frame.

    OpenCV's terms in its order ``(k1, k2, p1, p2, k3)``, one to five of them (the rest
    0). A real Kinect v2 or RealSense driver reports a factory calibration with its
    frames; it is close to the unit's lens but not exact, which is why a checkerboard
    calibration may refine it (``openptrack calibrate checkerboard --refine-intrinsics``).

    Parameters
    ----------
    distortion : tuple of float
        The unit's true lens: the renderer traces every pixel's ray through it.
    reported : tuple of float, optional
        The lens the unit's frames carry; ``None``: they carry none (a driver that does
        not know its lens), and the detector sees the images as a plain pinhole's.
    """

    distortion: tuple[float, ...] = Field(min_length=1, max_length=5)
    reported: tuple[float, ...] | None = Field(None, min_length=1, max_length=5)

    @model_validator(mode="after")
    def _bounded(self) -> SimLens:
        for key, terms in (("distortion", self.distortion), ("reported", self.reported)):
            for term in terms or ():
                if abs(term) > 2.0:
                    raise ValueError(
                        f"{key}: every lens term must lie within -2 and 2, received {term}"
                    )
        return self


class SensorConfig(StrictModel):
    """One depth sensor of the network.

    Parameters left at ``None`` take the sensor type's defaults: the rate from
    ``openptrack_py.sensor_types.SENSOR_TYPES``, the simulated miss and clutter figures
    from ``openptrack_py.sim.sensors.SENSOR_NOISE``.

    Parameters
    ----------
    id : str
        Unique sensor id; also the last chunk of its detection key.
    type : {"kinect1", "kinect2", "realsense", "sr4500"}
        Sensor model.
    host : str
        Machine that runs this sensor's node.
    source : {"sim", "camera", "recording"}
        Where frames come from. ``sim`` sensors are produced by the simulator node.
    rate_hz : float, optional
        Frame rate; the type's nominal rate if omitted.
    pose : Pose, optional
        Pose in the world frame.
    calibration : Path, optional
        Calibration file holding this sensor's entry (see
        :mod:`openptrack_py.calibration.files`); overrides the network's ``calibration``.
        A camera or recording sensor gives either ``pose`` or a calibration; a simulated
        one may give both: ``pose`` is where the simulator places it, the calibration
        what the pipeline believes.
    clock_offset_s : float
        Simulated constant offset of the sensor's clock.
    latency_s, latency_jitter_s : float
        Simulated mean delay from capture to publication, and its standard deviation.
    miss_probability : float, optional
        Simulated probability of missing a fully visible person.
    clutter_per_frame : float, optional
        Simulated mean number of false detections per frame.
    frame_drop_probability : float
        Simulated probability that a whole frame is lost.
    pose_error : PoseError
        Simulated calibration error.
    sim_lens : SimLens, optional
        Simulated unit's own lens and the lens its frames report (rendered sensors and
        checkerboard sessions); the type's distortion-free pinhole if omitted.
    input : str, optional
        Where a ``camera`` or ``recording`` sensor's frames come from, as for
        ``openptrack detect``: ``realsense[:SERIAL]``, ``azure-kinect[:N]``, a ``.bag``
        recording, a folder (``openptrack record-sensor`` output, TUM RGB-D) or a cloud.
    """

    id: Name
    type: SensorTypeName = "kinect2"
    host: str = "localhost"
    source: Literal["sim", "camera", "recording"] = "sim"
    rate_hz: float | None = Field(None, gt=0.0, le=120.0)
    pose: Pose | None = None
    calibration: Path | None = None
    clock_offset_s: float = Field(0.0, ge=-3600.0, le=3600.0)
    latency_s: float = Field(0.03, ge=0.0, le=5.0)
    latency_jitter_s: float = Field(0.005, ge=0.0, le=1.0)
    miss_probability: float | None = Field(None, ge=0.0, le=1.0)
    clutter_per_frame: float | None = Field(None, ge=0.0, le=50.0)
    frame_drop_probability: float = Field(0.0, ge=0.0, le=1.0)
    pose_error: PoseError = Field(default_factory=PoseError)
    sim_lens: SimLens | None = None
    input: str | None = None

    @model_validator(mode="after")
    def _pose_or_calibration(self) -> SensorConfig:
        if self.source != "sim" and self.pose is not None and self.calibration is not None:
            raise ValueError(
                "give either 'pose' or 'calibration', not both (only a simulated sensor "
                "takes both: its true placement and the calibration the pipeline uses)"
            )
        if self.sim_lens is not None and self.source != "sim":
            raise ValueError(
                f"sim_lens: only a simulated sensor has one (source is {self.source!r})"
            )
        return self
