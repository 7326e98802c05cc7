"""The ``detector`` section: the people detector run on each sensor's frames.

Per-sensor-type defaults (depth limit, pixel sampling, fewest points) come from
:data:`openptrack_py.sensor_types.SENSOR_TYPES`; the height presets are here.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from openptrack_py.config.base import StrictModel
from openptrack_py.sensor_types import SENSOR_TYPES

HEIGHT_PRESETS: dict[str, tuple[float, float, float]] = {
    "adult": (1.0, 2.3, 1.3),
    "child": (0.5, 1.2, 0.7),
    "everyone": (0.5, 2.3, 0.7),
}
"""Per preset: height band of the points clustered (min, max) and the lowest blob top."""


class GroundConfig(StrictModel):
    """How a detector finds the floor.

    Parameters
    ----------
    mode : {"auto", "calibration", "both"}
        ``auto``: RANSAC planes in the cloud, the lowest near-horizontal one; ``calibration``:
        the world's floor through the sensor's pose (or ``plane``); ``both``: estimate, and
        keep the estimate only while it agrees with calibration (OpenPTrack's rule).
    plane : tuple of float, optional
        A fixed plane ``a, b, c, d`` (``a*x + b*y + c*z + d = 0``) in the optical frame.
    lock : bool
        Keep the first plane found; otherwise it is refined by least squares every frame.
    expected_tilt_deg : float, optional
        Rough downward tilt of the sensor; from its pose when it has one, else unknown.
    angle_allowance_deg : float
        How far the floor's normal may be from the expected up direction (Zhang et al.,
        "Children Behavior Tracking and Personal Identification By Multiple Kinect
        Sensors", Eq. 1). With the tilt unknown, floors are tried for an upright camera
        (at least 45 degrees around its up), a steep one and one looking straight down
        (:func:`openptrack_py.detection.ground.choose_floor`).
    inlier_m : float
        RANSAC inlier distance.
    max_angle_diff_deg, max_offset_diff_m : float
        ``both``: agreement needed between estimated and calibrated planes.
    refine_rate : float
        Weight of each frame's least-squares fit when refining.
    accumulate_frames : int
        The floor is searched in this many recent frames together.
    """

    mode: Literal["auto", "calibration", "both"] = "both"
    plane: tuple[float, float, float, float] | None = None
    lock: bool = False
    expected_tilt_deg: float | None = Field(None, ge=-90.0, le=90.0)
    angle_allowance_deg: float = Field(20.0, gt=0.0, le=89.0)
    inlier_m: float = Field(0.03, gt=0.0, le=0.5)
    max_angle_diff_deg: float = Field(5.0, gt=0.0, le=90.0)
    max_offset_diff_m: float = Field(0.15, gt=0.0, le=5.0)
    refine_rate: float = Field(0.2, ge=0.0, le=1.0)
    accumulate_frames: int = Field(5, ge=1, le=300)


class BackgroundConfig(StrictModel):
    """Optional background learning and removal.

    Parameters
    ----------
    enabled : bool
        Learn the static scene, then drop points that fall in it.
    seconds : float
        Learning time at start-up.
    resolution_m : float
        Voxel size of the occupancy set.
    """

    enabled: bool = False
    seconds: float = Field(3.0, gt=0.0, le=600.0)
    resolution_m: float = Field(0.1, gt=0.0, le=1.0)


class HogConfig(StrictModel):
    """Optional HOG person check on the image at each blob's box.

    Parameters
    ----------
    enabled : bool
        Run the check.
    image : {"auto", "color", "ir"}
        Image to check: ``auto`` uses infrared on time-of-flight sensors (Kinect v2,
        SR4500) and colour otherwise.
    min_luminance : float
        Colour checks are skipped when the image's mean luminance (0-255) is below this.
    min_margin : float
        Blobs whose SVM margin is below this are dropped.
    weight : float
        Share of the HOG score in the confidence.
    """

    enabled: bool = False
    image: Literal["auto", "color", "ir"] = "auto"
    min_luminance: float = Field(20.0, ge=0.0, le=255.0)
    min_margin: float = Field(-2.5, ge=-20.0, le=20.0)
    weight: float = Field(0.5, ge=0.0, le=1.0)


class DetectorConfig(StrictModel):
    """The people detector that runs on each sensor's frames.

    Parameters
    ----------
    preset : {"adult", "child", "everyone"}
        Fills the height band: adult 1.0-2.3 m (blob top >= 1.3 m, OpenPTrack's),
        child 0.5-1.2 m (top >= 0.7 m; the band of Zhang et al.'s Kinect child tracking),
        everyone 0.5-2.3 m (top >= 0.7 m: children and adults together).
    min_height_m, max_height_m : float, optional
        Height band above the floor whose points are clustered (preset if omitted).
    min_top_m : float, optional
        A blob's highest point must be at least this high (preset if omitted).
    sampling_factor : int, optional
        Use every n-th pixel in each image direction; per sensor type if omitted
        (``detector_sampling_factor`` of :data:`~openptrack_py.sensor_types.SENSOR_TYPES`:
        1 for the low-resolution Kinect v1 and SR4500, 2 for Kinect v2 and RealSense).
    max_distance_m : float, optional
        Points farther than this along the optical axis are ignored, and blobs reaching
        it are dropped; the sensor type's ``detector_max_distance_m`` if omitted.
    voxel_size_m : float
        Cell of the floor grid the band is projected onto (and of down-sampling).
    min_points : int, optional
        Fewest points of a detection (after down-sampling); per sensor type if omitted
        (``detector_min_points``: fewer for low-resolution sensors).
    heads_minimum_distance_m : float
        Heads closer than this belong to one person; farther, a blob is split.
    min_size_m, max_size_m : float
        Width and length limits of a person's footprint (Zhang et al., Eq. 3).
    min_area_m2, max_area_m2 : float
        Area limits of a person's footprint.
    surface_offset_m : float
        The visible surface is nearer than the body's centre: positions are pushed this
        far along the viewing ray.
    appearance_bins : int
        Hue bins of the appearance signature (which has 3 achromatic bins after them:
        dark, grey, light; ``openptrack_py.detection.appearance``).
    rate_hz : float, optional
        Frames per second to process (the sensor's rate if omitted); older frames are
        dropped when the detector falls behind.
    ground, background, hog
        Sub-sections.
    """

    preset: Literal["adult", "child", "everyone"] = "adult"
    min_height_m: float | None = Field(None, ge=0.0, le=3.0)
    max_height_m: float | None = Field(None, gt=0.0, le=4.0)
    min_top_m: float | None = Field(None, ge=0.0, le=4.0)
    sampling_factor: int | None = Field(None, ge=1, le=16)
    max_distance_m: float | None = Field(None, gt=0.0, le=50.0)
    voxel_size_m: float = Field(0.06, ge=0.01, le=0.5)
    min_points: int | None = Field(None, ge=1, le=100_000)
    heads_minimum_distance_m: float = Field(0.3, gt=0.0, le=2.0)
    min_size_m: float = Field(0.1, ge=0.0, le=5.0)
    max_size_m: float = Field(1.0, gt=0.0, le=10.0)
    min_area_m2: float = Field(0.008, ge=0.0, le=10.0)
    max_area_m2: float = Field(0.8, gt=0.0, le=50.0)
    surface_offset_m: float = Field(0.06, ge=0.0, le=0.5)
    appearance_bins: int = Field(16, ge=4, le=64)
    rate_hz: float | None = Field(None, gt=0.0, le=120.0)
    ground: GroundConfig = Field(default_factory=GroundConfig)
    background: BackgroundConfig = Field(default_factory=BackgroundConfig)
    hog: HogConfig = Field(default_factory=HogConfig)

    @model_validator(mode="after")
    def _band(self) -> DetectorConfig:
        if self.band[0] >= self.band[1]:
            raise ValueError(
                f"min_height_m must be below max_height_m (received {self.band[0]} >= "
                f"{self.band[1]})"
            )
        if self.min_size_m >= self.max_size_m or self.min_area_m2 >= self.max_area_m2:
            raise ValueError("size limits: each minimum must be below its maximum")
        return self

    @property
    def band(self) -> tuple[float, float]:
        """Height band ``(min, max)`` in metres, after the preset."""
        low, high, _ = HEIGHT_PRESETS[self.preset]
        return (
            low if self.min_height_m is None else self.min_height_m,
            high if self.max_height_m is None else self.max_height_m,
        )

    def max_distance_for(self, sensor_type: str | None) -> float:
        """Depth limit for a sensor type (``max_distance_m`` when set; 10 m if unknown)."""
        if self.max_distance_m is not None:
            return self.max_distance_m
        kind = SENSOR_TYPES.get(sensor_type or "")
        return 10.0 if kind is None else kind.detector_max_distance_m

    def min_points_for(self, sensor_type: str | None) -> int:
        """Fewest points of a detection for a sensor type (``min_points`` when set)."""
        if self.min_points is not None:
            return self.min_points
        kind = SENSOR_TYPES.get(sensor_type or "")
        return 20 if kind is None else kind.detector_min_points

    def sampling_for(self, sensor_type: str | None, width: int) -> int:
        """Pixel sampling step for a sensor type and image width.

        ``sampling_factor`` when set; else the type's default; for an unknown type,
        every pixel of low-resolution images (320 wide or less) and every second one above.
        """
        if self.sampling_factor is not None:
            return self.sampling_factor
        kind = SENSOR_TYPES.get(sensor_type or "")
        if kind is not None:
            return kind.detector_sampling_factor
        return 1 if width <= 320 else 2

    @property
    def top_minimum(self) -> float:
        """Lowest allowed blob top in metres, after the preset."""
        return HEIGHT_PRESETS[self.preset][2] if self.min_top_m is None else self.min_top_m
