"""One simulated sensor's description: its type, pose, timing and noise model.

:class:`SensorSpec` is what the simulator knows of a sensor (from a network file's entry,
:meth:`SensorSpec.from_config`); :class:`SensorNoise` is how the simulated detector of a
sensor type errs, per type in :data:`SENSOR_NOISE`. The type's geometry (image, field of
view, ranges, rate) is in :mod:`openptrack_py.sensor_types`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from openptrack_py.calibration.files import SensorCalibration
from openptrack_py.config import Pose, PoseError, SensorConfig, SimLens
from openptrack_py.detection.appearance import signature_length
from openptrack_py.detection.frame import Intrinsics
from openptrack_py.errors import ConfigError
from openptrack_py.sensor_types import SENSOR_TYPES, SensorType

APPEARANCE_BINS = 16
"""Hue bins of the simulated appearance signature (each 22.5 degrees), as the detector's."""

APPEARANCE_LENGTH = signature_length(APPEARANCE_BINS)
"""Entries of the simulated appearance signature: the hue bins, then dark, grey, light
(:mod:`openptrack_py.detection.appearance`)."""


@dataclass(frozen=True)
class SensorNoise:
    """How the simulated detector of one sensor type errs.

    The type's geometry (image, field of view, ranges, rate) is in
    :data:`openptrack_py.sensor_types.SENSOR_TYPES`.

    Parameters
    ----------
    depth_sigma : tuple of float
        ``(s0, s1, s2)``: centroid noise along the ray ``s0 + s1*d + s2*d**2`` metres.
    lateral_sigma_m : float
        Centroid noise across the ray, metres.
    height_sigma_m : float
        Noise of the measured height, metres.
    miss_probability : float
        Probability of missing a fully visible person within the reliable range.
    clutter_per_frame : float
        Mean number of false detections per frame.
    split_probability : float
        Probability that a detected person also yields a second, spurious blob.
    """

    depth_sigma: tuple[float, float, float]
    lateral_sigma_m: float
    height_sigma_m: float
    miss_probability: float
    clutter_per_frame: float
    split_probability: float

    def depth_sigma_at(self, distance_m: np.ndarray | float) -> np.ndarray:
        """Standard deviation of the centroid along the ray at ``distance_m``."""
        s0, s1, s2 = self.depth_sigma
        d = np.asarray(distance_m, dtype=float)
        return s0 + s1 * d + s2 * d * d


SENSOR_NOISE: dict[str, SensorNoise] = {
    "kinect1": SensorNoise(
        depth_sigma=(0.02, 0.0, 0.0035), lateral_sigma_m=0.03, height_sigma_m=0.04,
        miss_probability=0.05, clutter_per_frame=0.02, split_probability=0.004,
    ),
    "kinect2": SensorNoise(
        depth_sigma=(0.03, 0.002, 0.0), lateral_sigma_m=0.025, height_sigma_m=0.03,
        miss_probability=0.02, clutter_per_frame=0.03, split_probability=0.003,
    ),
    "realsense": SensorNoise(
        depth_sigma=(0.03, 0.003, 0.0), lateral_sigma_m=0.025, height_sigma_m=0.03,
        miss_probability=0.03, clutter_per_frame=0.04, split_probability=0.004,
    ),
    "sr4500": SensorNoise(
        depth_sigma=(0.03, 0.002, 0.0), lateral_sigma_m=0.04, height_sigma_m=0.04,
        miss_probability=0.05, clutter_per_frame=0.03, split_probability=0.004,
    ),
}  # fmt: skip
"""The simulated detector's noise per sensor type (the types of ``SENSOR_TYPES``)."""


@dataclass(frozen=True)
class SensorSpec:
    """One simulated sensor: type, pose and fault model.

    Parameters
    ----------
    id : str
        Sensor id.
    type : SensorType
        Nominal facts of the sensor's type.
    pose : Pose
        True pose in the world.
    rate_hz : float
        Frame rate.
    clock_offset_s : float
        Constant offset added to every stamp the sensor writes.
    latency_s, latency_jitter_s : float
        Mean capture-to-publication delay and its standard deviation.
    miss_probability, clutter_per_frame : float
        This sensor's figures, used instead of those of its noise model
        (:meth:`from_config` takes them from the type's when the config leaves them out).
    frame_drop_probability : float
        Probability that a whole frame is never published.
    pose_error : PoseError
        Believed pose minus true pose.
    phase_s : float
        Time of the first frame after the scenario start.
    noise_override : SensorNoise, optional
        A noise model replacing the type's (see :attr:`noise`).
    calibration : SensorCalibration, optional
        The network's calibration entry for this sensor: detections are then reported
        through its pose (not ``pose`` + ``pose_error``) and stamps corrected by its clock
        offset, as a calibrated sensor's node does.
    lens : SimLens, optional
        The unit's own lens and the one its frames report (rendered sensors only); the
        type's distortion-free pinhole if ``None``.
    """

    id: str
    type: SensorType
    pose: Pose
    rate_hz: float
    clock_offset_s: float = 0.0
    latency_s: float = 0.03
    latency_jitter_s: float = 0.005
    miss_probability: float = 0.02
    clutter_per_frame: float = 0.03
    frame_drop_probability: float = 0.0
    pose_error: PoseError = field(default_factory=PoseError)
    phase_s: float = 0.0
    noise_override: SensorNoise | None = None
    calibration: SensorCalibration | None = None
    lens: SimLens | None = None

    @property
    def intrinsics(self) -> Intrinsics:
        """The unit's true camera model: its type's pinhole, with its own lens if any."""
        nominal = Intrinsics.for_sensor(self.type.name)
        return nominal if self.lens is None else nominal.with_distortion(self.lens.distortion)

    @property
    def reported_intrinsics(self) -> Intrinsics:
        """The camera model its frames carry: the pinhole, with the lens it reports if any."""
        nominal = Intrinsics.for_sensor(self.type.name)
        if self.lens is None or self.lens.reported is None:
            return nominal
        return nominal.with_distortion(self.lens.reported)

    @property
    def clock_correction_s(self) -> float:
        """What the sensor's node subtracts from its stamps: the calibrated clock offset."""
        return 0.0 if self.calibration is None else self.calibration.clock_offset_s

    @property
    def noise(self) -> SensorNoise:
        """The simulated detector's noise model: ``noise_override`` or the type's."""
        if self.noise_override is not None:
            return self.noise_override
        return SENSOR_NOISE[self.type.name]

    @classmethod
    def from_config(
        cls,
        cfg: SensorConfig,
        phase_s: float = 0.0,
        calibration: SensorCalibration | None = None,
    ) -> SensorSpec:
        """Build from a network file's sensor entry, filling type defaults.

        ``calibration`` is the sensor's entry in the network's calibration, if any.

        Raises
        ------
        ConfigError
            If the sensor has no pose (simulated sensors need one).
        """
        if cfg.pose is None:
            raise ConfigError(f"sensors.{cfg.id}.pose: a simulated sensor needs a pose")
        kind = SENSOR_TYPES[cfg.type]
        noise = SENSOR_NOISE[cfg.type]
        return cls(
            id=cfg.id,
            type=kind,
            pose=cfg.pose,
            rate_hz=cfg.rate_hz or kind.rate_hz,
            clock_offset_s=cfg.clock_offset_s,
            latency_s=cfg.latency_s,
            latency_jitter_s=cfg.latency_jitter_s,
            miss_probability=(
                noise.miss_probability if cfg.miss_probability is None else cfg.miss_probability
            ),
            clutter_per_frame=(
                noise.clutter_per_frame if cfg.clutter_per_frame is None else cfg.clutter_per_frame
            ),
            frame_drop_probability=cfg.frame_drop_probability,
            pose_error=cfg.pose_error,
            phase_s=phase_s,
            calibration=calibration,
            lens=cfg.sim_lens,
        )
