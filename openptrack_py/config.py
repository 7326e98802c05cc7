"""Typed configuration, loaded from YAML, with ``--set key.path=value`` overrides.

One **network file** describes a whole deployment: the site name, how Zenoh sessions
meet, every sensor (id, type, host, rate, pose or calibration file), the simulator and
each node's settings. Every node reads the same file and uses its own section.

Unknown keys and out-of-range values raise :class:`~openptrack_py.errors.ConfigError`
naming the key path, the allowed values and the value received::

    sensors.0.rat: unknown key; did you mean 'rate_hz'? (allowed: calibration, clock_offset_s, ...)
    sensors.1.rate_hz: must be > 0 (received -5)
"""

from __future__ import annotations

import difflib
import typing
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar

import yaml
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from openptrack_py.errors import ConfigError
from openptrack_py.sensor_types import SENSOR_TYPES, SensorTypeName

NAME_PATTERN = r"^[A-Za-z0-9_.\-]+$"
"""Identifiers (site, sensor ids, node names) become Zenoh key chunks: no '/', '*', '$'."""

Name = Annotated[str, Field(pattern=NAME_PATTERN, min_length=1, max_length=64)]
ScenarioName = Literal["crowd", "distance", "occlusions", "classroom", "installation", "stress"]
ENDPOINT_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream")
M = TypeVar("M", bound=BaseModel)


def _is_numeric(annotation: Any) -> bool:
    if annotation in (int, float):
        return True
    return any(_is_numeric(a) for a in typing.get_args(annotation))


class StrictModel(BaseModel):
    """Base of every config section: unknown keys are errors, values are immutable.

    Numbers must be finite, and YAML booleans (``true``, ``yes``, ``on``) are not
    numbers.
    """

    model_config = ConfigDict(
        extra="forbid", frozen=True, validate_default=True, allow_inf_nan=False
    )

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_numbers(cls, value: Any, info: Any) -> Any:
        if isinstance(value, bool):
            field = cls.model_fields.get(info.field_name)
            if field is not None and _is_numeric(field.annotation):
                raise ValueError("must be a number, not true/false")
        return value


def _check_endpoint(value: str) -> str:
    protocol, sep, address = value.partition("/")
    if not sep or protocol not in ENDPOINT_PROTOCOLS or not address:
        raise ValueError(
            f"must be a Zenoh endpoint '<protocol>/<address>' with protocol one of "
            f"{', '.join(ENDPOINT_PROTOCOLS)}, e.g. 'tcp/127.0.0.1:7447'"
        )
    return value


class ZenohConfig(StrictModel):
    """How this deployment's Zenoh sessions find each other.

    Every node is a Zenoh peer that listens on ``listen`` and connects to ``hub`` plus
    ``connect``. The launcher on ``hub_host`` listens on ``hub`` itself, so all nodes
    meet there and then link directly (peer gossip). Multicast scouting is off unless
    asked for, so nothing depends on the LAN's multicast set-up.

    Parameters
    ----------
    mode : {"peer", "client"}
        Zenoh session mode of every node.
    hub : str or None
        Rendezvous endpoint, e.g. ``tcp/192.168.1.10:7447``. ``None`` disables it.
    hub_host : str
        Host whose launcher listens on ``hub``.
    listen : list of str
        Each node's own listening endpoints (port 0 = any free port).
    connect : list of str
        Extra endpoints every node connects to (e.g. a zenohd router).
    multicast_scouting : bool
        Let sessions discover each other by UDP multicast as well.
    config_file : Path, optional
        A Zenoh JSON5 configuration applied first; the keys above override it.
    """

    mode: Literal["peer", "client"] = "peer"
    hub: str | None = "tcp/127.0.0.1:7447"
    hub_host: str = "localhost"
    listen: list[str] = Field(default_factory=lambda: ["tcp/127.0.0.1:0"])
    connect: list[str] = Field(default_factory=list)
    multicast_scouting: bool = False
    config_file: Path | None = None

    @field_validator("hub")
    @classmethod
    def _hub_endpoint(cls, value: str | None) -> str | None:
        return None if value is None else _check_endpoint(value)

    @field_validator("listen", "connect")
    @classmethod
    def _endpoints(cls, value: list[str]) -> list[str]:
        for item in value:
            _check_endpoint(item)
        return value


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
        Calibration file giving the pose (alternative to ``pose``).
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
    input: str | None = None

    @model_validator(mode="after")
    def _pose_or_calibration(self) -> SensorConfig:
        if self.pose is not None and self.calibration is not None:
            raise ValueError("give either 'pose' or 'calibration', not both")
        return self


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
    sensor_model: Literal["detections", "rgbd"] = "detections"
    ground_truth_rate_hz: float = Field(30.0, gt=0.0, le=240.0)
    use_scenario_sensors: bool = False
    start_time: float | None = Field(None, ge=0.0)


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
        How far the floor's normal may be from the expected up direction (seed 001 Eq. 1).
        With the tilt unknown the allowance is at least 45 degrees around an upright
        camera's up, and if no floor is found there, 30 degrees around a camera pitched
        50 degrees down.
    inlier_m : float
        RANSAC inlier distance.
    max_angle_diff_deg, max_offset_diff_m : float
        ``both``: agreement needed between estimated and calibrated planes.
    refine_rate : float
        Weight of each frame's least-squares fit when refining.
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
        child 0.5-1.2 m (top >= 0.7 m, seed 000), everyone 0.5-2.3 m (top >= 0.7 m:
        children and adults together).
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
        Width and length limits of a person's footprint (seed 001 Eq. 3).
    min_area_m2, max_area_m2 : float
        Area limits of a person's footprint.
    surface_offset_m : float
        The visible surface is nearer than the body's centre: positions are pushed this
        far along the viewing ray.
    appearance_bins : int
        Hue bins of the appearance signature.
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


class TrackerConfig(StrictModel):
    """The tracker: filter, gate, association, track lifecycle and multi-sensor fusion.

    Every parameter can be changed while the tracker runs
    (``openptrack config tracker key=value``); the change applies before the next step.

    Parameters
    ----------
    host : str
        Machine that runs the tracker node.
    gate_probability : float
        Probability mass of the chi-square gate: a detection can be associated with a
        track when its squared Mahalanobis distance is below
        ``chi2.ppf(gate_probability, dof)``, with ``dof`` the measurement dimension.
    acceleration_variance : float
        Spectral density of the white-noise acceleration of the constant-velocity
        model, m^2/s^3. Larger values follow sharper turns and widen the gate faster.
    measurement_sigma_m : float
        Standard deviation of a detection's position, metres.
    measurement_sigma_per_m2 : float
        Extra standard deviation per squared metre of detection distance (depth noise
        of structured-light sensors grows with the square of the range).
    velocity_in_motion_term : bool
        Also measure velocity, as the displacement of the detection from the track's
        estimate about a second earlier (OpenPTrack's option); the gate then has 4
        degrees of freedom.
    velocity_sigma_mps : float
        Standard deviation of that velocity measurement.
    detector_weight : float
        Weight of the detection's confidence in the association cost (negative: more
        confident detections are preferred).
    min_confidence_detections : float
        Detections below this confidence are ignored.
    min_confidence_initialization : float
        Only detections at least this confident start new tracks.
    detections_to_validate : int
        Associated detections a tentative track needs to become confirmed.
    sec_before_fake : float
        A tentative track not confirmed within this time is deleted.
    tentative_timeout_s : float
        A tentative track without a confident detection for this long is deleted, so the
        ``detections_to_validate`` detections must come close together (clutter rarely
        does; a person in view is detected every frame).
    sec_before_old : float
        A confirmed track without a detection of at least
        ``min_confidence_initialization`` for this long is deleted (low-confidence
        detections update a track but do not keep it alive).
    visibility_timeout_s : float
        A track unseen for longer than this is reported as not visible.
    initial_velocity_sigma_mps : float
        Standard deviation of a new track's unknown velocity.
    height_smoothing : float
        Weight of a new height measurement in the track height's moving average.
    publish_tentative : bool
        Publish tentative tracks too (with ``confirmed: false``).
    publish_unseen_s : float
        Confirmed tracks unseen for longer are kept (so the person gets the same id
        back when seen again before ``sec_before_old``) but not published.
    reorder_window_s : float
        How long a batch may wait for batches of other sensors captured earlier; 0
        applies batches in arrival order. Batches are released sooner when every other
        live sensor has already delivered a later frame.
    late_policy : {"replay", "drop"}
        What to do with a batch captured before batches already applied: go back to the
        tracker's state before its capture time and replay it and every later batch
        (exact), or drop it. Both are counted.
    max_lateness_s : float
        How far back replays reach; later batches are dropped.
    max_replay_steps : int
        A late batch that would replay more steps than this is dropped.
    clock_correction : {"arrival", "none"}
        ``arrival``: estimate each sensor's clock offset from the minimum of
        (arrival time - stamp) and align all sensors to their median, so a sensor whose
        clock is off by a constant is corrected within seconds (what remains is the
        difference in network latency). ``none``: trust the stamps.
    max_tracks : int
        Safety limit on simultaneous tracks.
    """

    host: str = "localhost"
    gate_probability: float = Field(0.95, ge=0.5, le=0.99999)
    acceleration_variance: float = Field(0.5, gt=0.0, le=1000.0)
    measurement_sigma_m: float = Field(0.08, gt=0.0, le=2.0)
    measurement_sigma_per_m2: float = Field(0.002, ge=0.0, le=0.1)
    velocity_in_motion_term: bool = False
    velocity_sigma_mps: float = Field(0.5, gt=0.0, le=10.0)
    detector_weight: float = Field(-1.0, ge=-10.0, le=0.0)
    min_confidence_detections: float = Field(0.0, ge=0.0, le=1.0)
    min_confidence_initialization: float = Field(0.5, ge=0.0, le=1.0)
    detections_to_validate: int = Field(3, ge=1, le=50)
    sec_before_fake: float = Field(2.4, gt=0.0, le=60.0)
    tentative_timeout_s: float = Field(0.5, gt=0.0, le=60.0)
    sec_before_old: float = Field(3.0, gt=0.0, le=600.0)
    visibility_timeout_s: float = Field(0.25, gt=0.0, le=10.0)
    initial_velocity_sigma_mps: float = Field(1.5, gt=0.0, le=20.0)
    height_smoothing: float = Field(0.1, gt=0.0, le=1.0)
    publish_tentative: bool = False
    publish_unseen_s: float = Field(0.5, ge=0.0, le=600.0)
    reorder_window_s: float = Field(0.05, ge=0.0, le=2.0)
    late_policy: Literal["replay", "drop"] = "replay"
    max_lateness_s: float = Field(1.0, ge=0.0, le=10.0)
    max_replay_steps: int = Field(64, ge=1, le=10_000)
    clock_correction: Literal["arrival", "none"] = "arrival"
    max_tracks: int = Field(1000, ge=1, le=100_000)


class SmootherConfig(StrictModel):
    """OpenPTrack's moving-average smoother, corrected (defaults: OpenPTrack v2).

    Parameters
    ----------
    rate_hz : float
        Output rate.
    window_size : int
        Positions averaged per track.
    position_lifetime_s : float
        Positions older than this leave the average.
    track_lifetime_s : float
        A track leaves the output this long after its last real detection
        (``track_lifetime_with_no_detections``).
    publish_empty : bool
        Send a frame every cycle even when no one is tracked; otherwise send an empty
        frame every ``heartbeat_interval_s`` only.
    heartbeat_interval_s : float
        Period of the empty frames when ``publish_empty`` is off.
    """

    rate_hz: float = Field(30.0, gt=0.0, le=240.0)
    window_size: int = Field(5, ge=1, le=100)
    position_lifetime_s: float = Field(0.6, gt=0.0, le=60.0)
    track_lifetime_s: float = Field(0.6, gt=0.0, le=60.0)
    publish_empty: bool = True
    heartbeat_interval_s: float = Field(1.0, gt=0.0, le=60.0)


class UdpSinkConfig(StrictModel):
    """One UDP JSON destination (OpenPTrack's ``ros2udp_converter``).

    Parameters
    ----------
    host : str
        Destination address: a host, a broadcast address (``x.x.x.255``) or a multicast
        group (``224.0.0.1``).
    port : int
        Destination port.
    mode : {"unicast", "broadcast", "multicast"}
        How to send.
    ttl : int
        Multicast time-to-live (hops).
    format : {"opt-v2", "opt-v1"}
        Root key ``people_tracks`` (v2, what the TouchDesigner component reads) or
        ``tracks`` (v1, what the Python, Processing, Max and Node examples read).
    trailing_nul : bool
        End each datagram with one NUL byte, as OpenPTrack does (the Processing example
        needs it; some Max externals break on it).
    heartbeat : bool
        Send ``alive_IDs`` / ``max_ID`` heartbeats (also when the room is empty).
    heartbeat_interval_s : float
        Heartbeat period.
    max_datagram_bytes : int
        Frames larger than this are split into several complete JSON messages with the
        same header (never two JSON objects in one datagram).
    """

    host: str = "127.0.0.1"
    port: int = Field(21234, ge=1, le=65535)
    mode: Literal["unicast", "broadcast", "multicast"] = "unicast"
    ttl: int = Field(1, ge=0, le=255)
    format: Literal["opt-v2", "opt-v1"] = "opt-v2"
    trailing_nul: bool = True
    heartbeat: bool = True
    heartbeat_interval_s: float = Field(0.25, gt=0.0, le=60.0)
    max_datagram_bytes: int = Field(65507, ge=512, le=65507)


class OscSinkConfig(StrictModel):
    """One OSC destination (python-osc).

    Parameters
    ----------
    host : str
        Destination address.
    port : int
        Destination port.
    prefix : str
        Address prefix: messages go to ``<prefix>/frame``, ``<prefix>/track`` and
        ``<prefix>/alive``.
    """

    host: str = "127.0.0.1"
    port: int = Field(7000, ge=1, le=65535)
    prefix: str = Field("/opt", pattern=r"^(/[A-Za-z0-9_\-]+)+$")


class WebConfig(StrictModel):
    """The WebSocket stream and the live web view.

    Parameters
    ----------
    host : str
        Address to listen on (``0.0.0.0`` to allow other machines).
    port : int
        HTTP and WebSocket port: the view is ``http://host:port/``, the stream
        ``ws://host:port/ws``.
    room : tuple of float, optional
        ``[x0, y0, x1, y1]`` drawn as the room; the sensors' reach when omitted.
    max_queue : int
        Frames a slow client may lag behind before it is dropped.
    """

    host: str = "127.0.0.1"
    port: int = Field(8080, ge=0, le=65535)
    room: tuple[float, float, float, float] | None = None
    max_queue: int = Field(32, ge=1, le=10_000)

    @field_validator("room")
    @classmethod
    def _room_has_area(
        cls, room: tuple[float, float, float, float] | None
    ) -> tuple[float, float, float, float] | None:
        if room is not None and not (room[2] > room[0] and room[3] > room[1]):
            raise ValueError("must be [x0, y0, x1, y1] with x1 > x0 and y1 > y0")
        return room


class OutputConfig(StrictModel):
    """An output node: smoother and sinks for creative apps.

    Parameters
    ----------
    name : str
        Node name (unique per site).
    host : str
        Machine that runs it.
    source : {"smoothed", "raw"}
        ``smoothed``: the moving-average smoother at a fixed rate. ``raw``: every
        tracker step as it arrives (lowest latency).
    smoother : SmootherConfig
        Smoother parameters.
    republish : bool
        Publish the smoothed tracks on ``opt/<site>/tracks/smoothed``.
    udp : list of UdpSinkConfig
        UDP JSON destinations.
    osc : list of OscSinkConfig
        OSC destinations.
    web : WebConfig, optional
        WebSocket stream and web view.
    """

    name: Name = "output"
    host: str = "localhost"
    source: Literal["smoothed", "raw"] = "smoothed"
    smoother: SmootherConfig = Field(default_factory=SmootherConfig)
    republish: bool = True
    udp: list[UdpSinkConfig] = Field(default_factory=list)
    osc: list[OscSinkConfig] = Field(default_factory=list)
    web: WebConfig | None = None


class RecorderConfig(StrictModel):
    """A recorder node: writes every message on ``keys`` to a JSON-lines file.

    Parameters
    ----------
    host : str
        Machine that runs the recorder.
    path : Path
        Output file (``.jsonl``); a timestamp is inserted before the suffix if it exists.
    keys : list of str
        Key expressions below ``opt/<site>/`` to record.
    """

    host: str = "localhost"
    path: Path = Path("recordings/run.jsonl")
    keys: list[str] = Field(default_factory=lambda: ["detections/**", "tracks", "ground_truth"])


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
    """

    site: Name = "default"
    zenoh: ZenohConfig = Field(default_factory=ZenohConfig)
    sensors: list[SensorConfig] = Field(default_factory=list)
    sim: SimConfig | None = None
    tracker: TrackerConfig | None = None
    outputs: list[OutputConfig] = Field(default_factory=list)
    recorder: RecorderConfig | None = None
    detector: DetectorConfig = Field(default_factory=DetectorConfig)
    stats_interval_s: float = Field(2.0, gt=0.0, le=3600.0)

    @model_validator(mode="after")
    def _consistent(self) -> NetworkConfig:
        ids = [s.id for s in self.sensors]
        duplicates = sorted({i for i in ids if ids.count(i) > 1})
        if duplicates:
            raise ValueError(f"sensor ids must be unique; repeated: {', '.join(duplicates)}")
        names = [o.name for o in self.outputs]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"output names must be unique; repeated: {', '.join(twice)}")
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
        if simulated and self.sim is None:
            raise ValueError(
                f"sensors {', '.join(simulated)} have source 'sim' but there is no 'sim' section"
            )
        return self

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


# --------------------------------------------------------------------------- loading


def parse_override_value(text: str) -> Any:
    """Parse an override's value as a YAML scalar or flow collection."""
    try:
        return yaml.safe_load(text) if text.strip() else ""
    except yaml.YAMLError:
        return text


def apply_overrides(data: dict[str, Any], overrides: Iterable[str]) -> dict[str, Any]:
    """Apply ``key.path=value`` overrides to a raw config mapping.

    Path chunks index mappings by key and lists by position, or by the ``id`` / ``name``
    of their items (``sensors.kinect_a.rate_hz=15``). Missing mappings are created.

    Raises
    ------
    ConfigError
        If an override is not ``key=value`` or its path cannot be followed.
    """
    for override in overrides:
        path, sep, text = override.partition("=")
        if not sep or not path.strip():
            raise ConfigError(f"override {override!r}: expected key.path=value")
        chunks = path.strip().split(".")
        node: Any = data
        for i, chunk in enumerate(chunks):
            where = ".".join(chunks[: i + 1])
            last = i == len(chunks) - 1
            if isinstance(node, dict):
                if last:
                    node[chunk] = parse_override_value(text)
                else:
                    if node.get(chunk) is None:
                        node[chunk] = {}
                    node = node[chunk]
            elif isinstance(node, list):
                index = _list_index(node, chunk, where)
                if last:
                    node[index] = parse_override_value(text)
                else:
                    node = node[index]
            else:
                parent = ".".join(chunks[:i])
                raise ConfigError(f"override {override!r}: {parent} is not a mapping or list")
    return data


def _list_index(items: list, chunk: str, where: str) -> int:
    if chunk.lstrip("-").isdigit():
        index = int(chunk)
        if -len(items) <= index < len(items):
            return index % len(items)
        raise ConfigError(f"{where}: index out of range (list has {len(items)} items)")
    for index, item in enumerate(items):
        if isinstance(item, dict) and chunk in (item.get("id"), item.get("name")):
            return index
    names = [str(it.get("id", it.get("name"))) for it in items if isinstance(it, dict)]
    raise ConfigError(f"{where}: no item with id {chunk!r} (known: {', '.join(names) or 'none'})")


def _inner_models(annotation: Any) -> list[type[BaseModel]]:
    """The BaseModel classes reachable from a field annotation (through Optional, list...)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    origin = typing.get_origin(annotation)
    if origin is None:
        return []
    found: list[type[BaseModel]] = []
    for arg in typing.get_args(annotation):
        if origin is Annotated and arg is not typing.get_args(annotation)[0]:
            continue
        found.extend(_inner_models(arg))
    return found


def _model_at(model: type[BaseModel], loc: Sequence[int | str]) -> type[BaseModel] | None:
    current: type[BaseModel] | None = model
    for chunk in loc:
        if current is None:
            return None
        if isinstance(chunk, int):
            continue
        field = current.model_fields.get(chunk)
        if field is None:
            return None
        inner = _inner_models(field.annotation)
        current = inner[0] if inner else None
    return current


def _allowed_text(ctx: dict[str, Any]) -> str | None:
    for key, op in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
        if key in ctx:
            return f"must be {op} {ctx[key]}"
    if "expected" in ctx:
        return f"must be one of {ctx['expected']}"
    if "pattern" in ctx:
        return f"must match {ctx['pattern']}"
    return None


def _format_error(root: type[BaseModel], err: dict[str, Any], data: Any) -> str:
    loc = [c for c in err["loc"] if not (isinstance(c, str) and c.startswith("function-"))]
    where = ".".join(str(c) for c in loc) or "(top level)"
    received = err.get("input")
    if err["type"] == "extra_forbidden":
        parent = _model_at(root, loc[:-1])
        allowed = sorted(parent.model_fields) if parent else []
        hint = difflib.get_close_matches(str(loc[-1]), allowed, n=1)
        did_you_mean = f"; did you mean {hint[0]!r}?" if hint else ""
        return f"{where}: unknown key{did_you_mean} (allowed: {', '.join(allowed)})"
    if err["type"] == "missing":
        return f"{where}: required key is missing"
    ctx = err.get("ctx") or {}
    text = _allowed_text(ctx)
    if text is None:
        text = err["msg"]
        text = text.removeprefix("Value error, ")
        text = text[0].lower() + text[1:] if text else text
    if err["type"].startswith("literal") or "expected" in ctx:
        return f"{where}: {text} (received {received!r})"
    if isinstance(received, dict) and not loc:
        return f"{where}: {text}"
    return f"{where}: {text} (received {received!r})"


def validate_config(model: type[M], data: Any, source: str = "config") -> M:
    """Validate a raw mapping against ``model``.

    Raises
    ------
    ConfigError
        Listing every problem, one per line, each naming its key path.
    """
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(
            f"{source}: expected a mapping at the top level, got {type(data).__name__}"
        )
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        lines = [_format_error(model, e, data) for e in exc.errors(include_url=False)]
        raise ConfigError(f"{source}: invalid configuration\n  " + "\n  ".join(lines)) from None


def read_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping from ``path``.

    Raises
    ------
    ConfigError
        If the file is missing, unreadable or not YAML.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise ConfigError(f"{path}:{where}: not valid YAML ({problem})") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(
            f"{path}: expected a mapping at the top level, got {type(data).__name__}"
        )
    return data


def load_config(
    model: type[M], path: str | Path | None = None, overrides: Iterable[str] = ()
) -> M:
    """Load ``model`` from a YAML file (or defaults), apply overrides, validate.

    Parameters
    ----------
    model : type
        The config model, e.g. :class:`NetworkConfig`.
    path : str or Path, optional
        YAML file; the model's defaults are used when omitted.
    overrides : iterable of str
        ``key.path=value`` items applied after reading the file.

    Raises
    ------
    ConfigError
        For unreadable files, bad overrides or invalid values.
    """
    data = read_yaml(path) if path is not None else {}
    data = apply_overrides(data, overrides)
    return validate_config(model, data, str(path) if path is not None else "config")


def load_network(path: str | Path | None = None, overrides: Iterable[str] = ()) -> NetworkConfig:
    """Load a network file (see :class:`NetworkConfig`)."""
    return load_config(NetworkConfig, path, overrides)


def to_yaml(config: BaseModel) -> str:
    """Render a config (defaults included) as YAML."""
    return yaml.safe_dump(config.model_dump(mode="json"), sort_keys=False)
