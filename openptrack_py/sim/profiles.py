"""Noise profiles: how far the simulated sensors are from a perfect people detector.

A :class:`NoiseProfile` adds realism on top of each sensor type's own noise model
(:data:`~openptrack_py.sim.sensor_spec.SENSOR_NOISE`): a detector's centroid error that
persists over frames, outliers, off-centre detections of half-hidden people, more misses,
confident false positives (transient ones and static "decoys"), calibration error,
clock offsets, jitter and dropped frames, people merging into one blob and persistent
splits. Three named profiles, in :data:`PROFILES`:

``ideal``
    The simulator as it was before profiles: the sensor type's noise only, no extra
    random draws. Regression tests and fingerprints use it.
``realistic``
    Calibrated from outside evidence (cited per value in :data:`REALISTIC`): what
    people detectors on depth sensors really deliver. Evaluate trackers on this.
``harsh``
    A badly calibrated network in a cluttered room, for robustness margins.

Sweeps derive variants: ``PROFILES["realistic"].scaled(noise=2.0)``,
:meth:`NoiseProfile.with_calibration_error`, :meth:`NoiseProfile.with_false_positives`,
or :func:`dataclasses.replace` for any field (every variant is validated).

Simulated identity embeddings (:mod:`~openptrack_py.sim.embeddings`) are off in every
named profile: :meth:`NoiseProfile.with_embeddings` or ``"<name>+embeddings"`` has them.

:func:`~openptrack_py.sim.sensor_faults.draw_sensor_faults` turns a profile into
per-sensor figures (calibration offset, clock offset, jitter, drops, misses) drawn from
the scenario seed; the per-frame mechanisms live in
:mod:`~openptrack_py.sim.centroid_error` and :mod:`~openptrack_py.sim.false_positives`.
The module is long because every figure of the named profiles carries its evidence.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from openptrack_py.errors import ConfigError
from openptrack_py.sensor_types import SENSOR_TYPES
from openptrack_py.sim.sensor_spec import SENSOR_NOISE

__all__ = [
    "FALSE_POSITIVE_TYPE_FACTOR",
    "HARSH",
    "IDEAL",
    "PROFILES",
    "PROFILE_NAMES",
    "REALISTIC",
    "NoiseProfile",
    "resolve_profile",
]

FALSE_POSITIVE_TYPE_FACTOR: Mapping[str, float] = MappingProxyType(
    {"kinect2": 1.0, "kinect1": 0.3, "realsense": 1.0, "sr4500": 0.9}
)
"""Confident false positives of each sensor type relative to a Kinect v2's.

Scales the transient false positives, the decoy sightings and the persistent splits.

OpenPTrack paper, Table 2 (Crowd): FP 9.3 % with Kinect v2, 8.7 % with the SR4500, 1.0 %
with Kinect v1 (whose detector also finds far fewer people: FN 54.2 %; 0.3 rather than
0.1 because part of Kinect v1's low FP is that missing; OpenPTrack re-scores Kinect v1
candidates with Haar features and AdaBoost on disparity, which rejects most objects).
RealSense: no published figure; taken as Kinect v2.
"""

_RANGES: dict[str, tuple[float, float]] = {
    "noise_scale": (0.0, 10.0),
    "body_sigma_m": (0.0, 1.0),
    "correlated_sigma_m": (0.0, 1.0),
    "correlation_time_s": (1e-3, 60.0),
    "outlier_probability": (0.0, 1.0),
    "outlier_sigma_m": (0.0, 5.0),
    "occlusion_shift": (0.0, 1.0),
    "false_positives_per_frame": (0.0, 20.0),
    "false_positive_duration_s": (1e-3, 10.0),
    "false_positive_max_confidence": (0.0, 1.0),
    "false_positive_drift_m_s": (0.0, 2.0),
    "decoys_per_sensor": (0.0, 10.0),
    "decoy_detection_probability": (0.0, 1.0),
    "clock_offset_s": (0.0, 10.0),
    "latency_jitter_s": (0.0, 1.0),
    "gait_bob_m": (0.0, 0.2),
    "frame_drop_probability": (0.0, 1.0),
    "merge_distance_m": (0.0, 2.0),
    "split_duration_s": (0.0, 10.0),
    "embedding_confusion_probability": (0.0, 1.0),
}
_PAIR_RANGES: dict[str, tuple[float, float]] = {
    "decoy_confidence": (0.0, 1.0),
    "calibration_offset_m": (0.0, 2.0),
    "calibration_yaw_deg": (0.0, 20.0),
    "floor_tilt_deg": (0.0, 10.0),
}


@dataclass(frozen=True)
class NoiseProfile:
    """How far the simulated detectors are from perfect, on top of each type's noise.

    Every default is the ``ideal`` value (the feature off). Distances are metres on the
    floor, times seconds, probabilities per detection or per frame as stated.

    Parameters
    ----------
    name : str
        Profile name (variants append what they changed).
    noise_scale : float
        Multiplier of every centroid error term: the type's along-ray and across-ray
        noise, ``body_sigma_m``, ``correlated_sigma_m`` and ``outlier_sigma_m``. For
        sweeps; 1 in the named profiles.
    body_sigma_m : float
        White centroid error per floor axis, metres: the body's own motion (arm swing,
        leaning, a bag) and the segmentation of each frame, independent frame to frame.
    correlated_sigma_m : float
        Stationary standard deviation per floor axis, metres, of a per-person, per-sensor
        centroid error that persists over frames (an Ornstein-Uhlenbeck process): what a
        detector's view of one body gets consistently wrong, so that one sensor's
        detections of a person sit off another's. This term and the outliers grow with
        distance like the sensor type's depth noise (never shrink below their value at
        :data:`~openptrack_py.sim.centroid_error.REFERENCE_DISTANCE_M`).
    correlation_time_s : float
        Time constant of the persistent error, seconds.
    outlier_probability : float
        Probability that a detection's centroid is an outlier (a part of the background
        or a neighbour in the cluster, a missing limb).
    outlier_sigma_m : float
        Standard deviation per floor axis of an outlier's extra error, metres.
    occlusion_shift : float
        Fraction (0-1) of the visible part's sideways offset applied to a partly hidden
        person's detection: a detector takes the centroid of the points it sees.
    miss_probability : mapping of str to float, optional
        Base probability, per sensor type, of missing a fully visible person within the
        reliable range (beyond it, misses grow as before). ``None``: the type's own
        (:data:`~openptrack_py.sim.sensor_spec.SENSOR_NOISE`). A sensor whose network
        entry sets ``miss_probability`` keeps it.
    false_positives_per_frame : float
        Mean number of transient confident false positives present in a Kinect v2 frame
        (other types scale it by :data:`FALSE_POSITIVE_TYPE_FACTOR`).
    false_positive_duration_s : float
        Mean lifetime of a transient false positive (exponential), seconds.
    false_positive_max_confidence : float
        Highest confidence of a transient false positive; confidences are uniform from
        0.25 (or this, if lower) up to it.
    false_positive_drift_m_s : float
        Largest drift speed of a transient false positive, m/s.
    decoys_per_sensor : float
        Static false positives ("decoys": a coat rack, a poster board, a fan) per sensor
        of the scenario, rounded up: ``ceil(decoys_per_sensor * sensors)``. Placed from
        the scenario seed on free floor in some sensor's view; they do not block people.
    decoy_detection_probability : float
        Per frame, probability that a Kinect v2 that can see a decoy reports it (other
        types scale it by :data:`FALSE_POSITIVE_TYPE_FACTOR`).
    decoy_confidence : (float, float)
        Range of a decoy detection's confidence.
    calibration_offset_m : (float, float)
        Range of each sensor's calibration position error, metres, in a random direction
        (only in networks of two or more sensors, and only for sensors whose network
        entry leaves ``pose_error`` at zero).
    calibration_yaw_deg : (float, float)
        Range of each sensor's calibration yaw error, degrees, random sign.
    clock_offset_s : float
        Each sensor's clock offset is uniform in ``[-clock_offset_s, clock_offset_s]``
        unless its network entry sets one.
    latency_jitter_s : float
        Least standard deviation of the capture-to-publication delay, seconds.
    frame_drop_probability : float
        Least probability that a whole frame is lost.
    floor_tilt_deg : (float, float)
        Range of the tilt of each sensor's floor plane, degrees (direction random):
        measured heights are off by its tangent times the distance from the sensor
        (:mod:`~openptrack_py.sim.height_error`).
    gait_bob_m : float
        How far a walking person's measured height rises and falls about its mean, at
        normal walking speed: lowest at each step's double support, near the standing
        height in mid-stance.
    merge_distance_m : float
        People closer than this (centre to centre) come out as one detection.
    split_probability : float, optional
        Per detected person and frame, probability that a spurious second blob appears
        beside them (for persistent splits: a Kinect v2's, other types scale it by
        :data:`FALSE_POSITIVE_TYPE_FACTOR`); ``None``: the sensor type's own.
    split_duration_s : float
        Mean lifetime of a split blob, seconds; 0: splits last one frame (``ideal``).
    embeddings : bool
        People facing a sensor within reach carry a simulated identity embedding
        (``face``, ``face_confidence``; :mod:`~openptrack_py.sim.embeddings`), drawn
        from generators of their own: every other draw is the same either way.
    embedding_confusion_probability : float
        Probability that an embedding is drawn near another person's identity.

    Raises
    ------
    ConfigError
        For a value out of range, naming the field, the allowed range and the value.
    """

    name: str
    noise_scale: float = 1.0
    body_sigma_m: float = 0.0
    correlated_sigma_m: float = 0.0
    correlation_time_s: float = 1.0
    outlier_probability: float = 0.0
    outlier_sigma_m: float = 0.0
    occlusion_shift: float = 0.0
    miss_probability: Mapping[str, float] | None = None
    false_positives_per_frame: float = 0.0
    false_positive_duration_s: float = 0.4
    false_positive_max_confidence: float = 0.0
    false_positive_drift_m_s: float = 0.0
    decoys_per_sensor: float = 0.0
    decoy_detection_probability: float = 0.0
    decoy_confidence: tuple[float, float] = (0.5, 0.8)
    calibration_offset_m: tuple[float, float] = (0.0, 0.0)
    calibration_yaw_deg: tuple[float, float] = (0.0, 0.0)
    clock_offset_s: float = 0.0
    latency_jitter_s: float = 0.0
    frame_drop_probability: float = 0.0
    floor_tilt_deg: tuple[float, float] = (0.0, 0.0)
    gait_bob_m: float = 0.0
    merge_distance_m: float = 0.3
    split_probability: float | None = None
    split_duration_s: float = 0.0
    embeddings: bool = False
    embedding_confusion_probability: float = 0.02

    def __post_init__(self) -> None:
        where = f"profile {self.name}"
        if not isinstance(self.embeddings, bool):
            raise ConfigError(f"{where}: embeddings must be true or false ({self.embeddings!r})")
        for key, (lo, hi) in _RANGES.items():
            _check(where, key, getattr(self, key), lo, hi)
        for key, (lo, hi) in _PAIR_RANGES.items():
            pair = getattr(self, key)
            if not (isinstance(pair, tuple) and len(pair) == 2):
                raise ConfigError(f"{where}: {key} must be a (low, high) pair (received {pair!r})")
            _check(where, f"{key}[0]", pair[0], lo, hi)
            _check(where, f"{key}[1]", pair[1], pair[0], hi)
        if self.split_probability is not None:
            _check(where, "split_probability", self.split_probability, 0.0, 1.0)
        if self.miss_probability is not None:
            unknown = sorted(set(self.miss_probability) - set(SENSOR_TYPES))
            if unknown:
                raise ConfigError(
                    f"{where}: miss_probability: unknown sensor type {', '.join(unknown)} "
                    f"(allowed: {', '.join(SENSOR_TYPES)})"
                )
            for kind, p in self.miss_probability.items():
                _check(where, f"miss_probability[{kind}]", p, 0.0, 1.0)
            frozen = MappingProxyType(dict(self.miss_probability))
            object.__setattr__(self, "miss_probability", frozen)

    def __hash__(self) -> int:
        values = (getattr(self, f.name) for f in dataclasses.fields(self))
        items = (tuple(sorted(v.items())) if isinstance(v, Mapping) else v for v in values)
        return hash(tuple(items))

    @property
    def centroid_error(self) -> bool:
        """Whether the profile adds centroid error terms beyond the sensor type's."""
        return self.body_sigma_m > 0 or self.correlated_sigma_m > 0 or self.outlier_probability > 0

    @property
    def sensor_faults(self) -> bool:
        """Whether the profile changes per-sensor figures (calibration, clock, drops...).

        See :func:`~openptrack_py.sim.sensor_faults.draw_sensor_faults`.
        """
        return (
            self.calibration_offset_m != (0.0, 0.0)
            or self.calibration_yaw_deg != (0.0, 0.0)
            or self.clock_offset_s > 0
            or self.latency_jitter_s > 0
            or self.frame_drop_probability > 0
            or self.miss_probability is not None
        )

    def miss_probability_for(self, sensor_type: str) -> float:
        """The base miss probability of ``sensor_type`` under this profile."""
        if self.miss_probability is not None and sensor_type in self.miss_probability:
            return self.miss_probability[sensor_type]
        return SENSOR_NOISE[sensor_type].miss_probability

    def scaled(
        self, *, noise: float = 1.0, misses: float = 1.0, false_positives: float = 1.0
    ) -> NoiseProfile:
        """A variant with the centroid noise, misses and false positives multiplied.

        Parameters
        ----------
        noise : float
            Multiplies ``noise_scale`` (every centroid error term).
        misses : float
            Multiplies every sensor type's base miss probability (capped at 1).
        false_positives : float
            Multiplies the transient false positives and the decoys per sensor.
        """
        kinds = {k: min(1.0, self.miss_probability_for(k) * misses) for k in SENSOR_TYPES}
        return dataclasses.replace(
            self,
            name=_variant(self.name, noise=noise, misses=misses, false_positives=false_positives),
            noise_scale=self.noise_scale * noise,
            miss_probability=kinds if misses != 1.0 else self.miss_probability,
            false_positives_per_frame=self.false_positives_per_frame * false_positives,
            decoys_per_sensor=self.decoys_per_sensor * false_positives,
        )

    def with_calibration_error(
        self, offset_m: float, yaw_deg: float | None = None
    ) -> NoiseProfile:
        """A variant where every sensor's calibration is ``offset_m`` off (and ``yaw_deg``).

        Parameters
        ----------
        offset_m : float
            Each sensor's calibration position error, metres (its direction is drawn per
            sensor).
        yaw_deg : float, optional
            Each sensor's yaw error, degrees (its sign is drawn per sensor); the
            profile's range when omitted.
        """
        yaw = self.calibration_yaw_deg if yaw_deg is None else (yaw_deg, yaw_deg)
        return dataclasses.replace(
            self,
            name=_variant(self.name, calibration_m=offset_m),
            calibration_offset_m=(offset_m, offset_m),
            calibration_yaw_deg=yaw,
        )

    def with_embeddings(self, on: bool = True, confusion: float | None = None) -> NoiseProfile:
        """A variant with simulated identity embeddings ``on`` (or off).

        ``confusion``: probability that one is another person's (the profile's if omitted).
        """
        name = self.name.removesuffix(EMBEDDINGS_SUFFIX)
        rate = self.embedding_confusion_probability if confusion is None else confusion
        return dataclasses.replace(
            self,
            name=name + EMBEDDINGS_SUFFIX if on else name,
            embeddings=on,
            embedding_confusion_probability=rate,
        )

    def with_false_positives(
        self,
        per_frame: float,
        max_confidence: float | None = None,
        decoys_per_sensor: float | None = None,
    ) -> NoiseProfile:
        """A variant with ``per_frame`` transient false positives up to ``max_confidence``.

        Parameters
        ----------
        per_frame : float
            Mean number of transient false positives in a Kinect v2 frame.
        max_confidence : float, optional
            Their highest confidence; the profile's when omitted.
        decoys_per_sensor : float, optional
            Decoys per sensor; the profile's when omitted.
        """
        return dataclasses.replace(
            self,
            name=_variant(self.name, false_positives_per_frame=per_frame),
            false_positives_per_frame=per_frame,
            false_positive_max_confidence=(
                self.false_positive_max_confidence if max_confidence is None else max_confidence
            ),
            decoys_per_sensor=(
                self.decoys_per_sensor if decoys_per_sensor is None else decoys_per_sensor
            ),
        )


def _check(where: str, key: str, value: object, lo: float, hi: float) -> None:
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    if not ok or not (lo <= float(value) <= hi) or math.isnan(float(value)):  # type: ignore[arg-type]
        raise ConfigError(f"{where}: {key} must be in [{lo:g}, {hi:g}] (received {value!r})")


def _variant(name: str, **changes: float) -> str:
    parts = [f"{k}={v:g}" for k, v in changes.items() if v != 1.0 or k.endswith(("_m", "frame"))]
    return f"{name}+{','.join(parts)}" if parts else name


IDEAL = NoiseProfile(name="ideal")
"""The sensor types' own noise only: the simulator as it was before profiles."""

REALISTIC = NoiseProfile(
    name="realistic",
    # Centroid error. Childcare paper (Simultaneous children recognition and tracking
    # ... using Kinect sensors, §2.1): single-frame detections are "around 10 cm" off
    # on average "with the standard deviation 8 cm". A 2-D Gaussian's error has
    # std/mean = 0.52; 0.08/0.10 = 0.8 needs a heavier tail, hence a Gaussian core plus
    # outliers. Together with Kinect v2's own noise these give, measured on people
    # 2-5 m from one Kinect v2 (benchmarks.profile_rates), mean 0.10 m, std 0.08 m.
    body_sigma_m=0.04,
    correlated_sigma_m=0.05,
    # A detector's error on one body persists over frames (the same pose, the same
    # partial view); OpenPTrack paper §4.3: one person seen by two sensors produces two
    # tracks unless their detections coincide, and users report "two ids ... offset by
    # about 10 cm" at camera boundaries (OpenPTrack issue v1 #96).
    correlation_time_s=1.0,
    outlier_probability=0.05,
    outlier_sigma_m=0.25,
    # The centroid of the visible points (OpenPTrack's PersonCluster centroid).
    occlusion_shift=1.0,
    # Misses per frame of a fully visible person in range. OpenPTrack paper Table 3
    # (Distance, 2 people, one sensor): FN 7.1 % Kinect v2, 34.5 % SR4500, 43.5 %
    # Kinect v1 (the last two also lose people past their range, which the range model
    # adds); Table 2 (Crowd) 29.5 / 40.4 / 54.2 % with occlusions.
    miss_probability={"kinect2": 0.05, "kinect1": 0.12, "realsense": 0.08, "sr4500": 0.12},
    # Confident false positives. OpenPTrack paper Tables 2-4: FP 9.3 % (Crowd), 3.2 %
    # (Distance), 6.2 % (Occlusions) of the ground-truth people with Kinect v2, after
    # its tracker's confirmation; per frame, a detector reports more.
    false_positives_per_frame=0.04,
    false_positive_duration_s=0.4,
    false_positive_max_confidence=0.8,
    false_positive_drift_m_s=0.15,
    # Static false positives that recur at one place: "a fan got tracked" (OpenPTrack
    # issue v1 #54).
    decoys_per_sensor=0.5,
    decoy_detection_probability=0.15,
    decoy_confidence=(0.5, 0.8),
    # Calibration: OpenPTrack paper §4.3/§8.1: after the checkerboard calibration the
    # sensors' detections of one walking person do not coincide (Figures 7, 17), and
    # the refinement cuts their distance to the average cloud 2-4x; users report
    # duplicate ids "about 10 cm apart" at camera boundaries (issue v1 #96) and double
    # detections from a constant offset (issue v1 #156). The ranges (5-12 cm and 1-2
    # degrees per sensor, so 0.1-0.2 m between two sensors) are our reading of those,
    # not a published figure: a calibrated network, not (or partly) refined.
    calibration_offset_m=(0.05, 0.12),
    calibration_yaw_deg=(1.0, 2.0),
    # Clocks: OpenPTrack needs NTP between machines and users find it confusing (issues
    # #66, #103); NTP on a LAN keeps clocks within milliseconds to tens of milliseconds
    # (an assumption, like the jitter). Drops: OpenPTrack's recorded track streams
    # arrive at 25-29 Hz of a nominal 30 with gaps in seq (its sim/data recordings);
    # 1 % of sensor frames is a conservative share of that.
    clock_offset_s=0.02,
    latency_jitter_s=0.015,
    frame_drop_probability=0.01,
    # Heights (sim/height_error.py): a walking person's head rises and falls about 5 cm
    # peak to peak per step (Saunders, Inman and Eberhart 1953); each sensor measures
    # from a floor plane fitted to its own points, taken to be good to 0.25-1 degree
    # (our reading, not a published figure: 1 degree is 7 cm of height at 4 m).
    floor_tilt_deg=(0.25, 1.0),
    gait_bob_m=0.025,
    # Merges: OpenPTrack's detector clusters points 0.12 m apart into one body and
    # splits a cluster only at heads >= 0.3 m apart (heads_minimum_distance); people
    # walking shoulder to shoulder are about 0.45 m apart centre to centre.
    merge_distance_m=0.45,
    # Splits: raised arms and fast turns spawn extra ids (OpenPTrack issues #37, v1 #96).
    split_probability=0.003,
    split_duration_s=0.4,
)
"""Detectors as real people detectors on depth sensors deliver them (evidence per value)."""

# Harsh: each figure about 1.5-3x realistic's. A margin for robustness, not a
# measurement: no source reports a network this bad as typical.
HARSH = dataclasses.replace(
    REALISTIC,
    name="harsh",
    body_sigma_m=0.05,
    correlated_sigma_m=0.07,
    outlier_probability=0.08,
    outlier_sigma_m=0.35,
    miss_probability={"kinect2": 0.12, "kinect1": 0.25, "realsense": 0.15, "sr4500": 0.2},
    false_positives_per_frame=0.2,
    decoys_per_sensor=1.0,
    decoy_detection_probability=0.4,
    # An unrefined calibration, twice the realistic offsets (no published figure).
    calibration_offset_m=(0.10, 0.20),
    calibration_yaw_deg=(2.0, 3.0),
    clock_offset_s=0.1,
    latency_jitter_s=0.04,
    frame_drop_probability=0.03,
    floor_tilt_deg=(0.5, 2.0),
    merge_distance_m=0.6,
    split_probability=0.01,
    split_duration_s=0.6,
)
"""A badly calibrated network in a cluttered room: for robustness margins."""

PROFILES: Mapping[str, NoiseProfile] = MappingProxyType(
    {"ideal": IDEAL, "realistic": REALISTIC, "harsh": HARSH}
)
"""The named profiles (a network file's ``sim.profile``)."""

PROFILE_NAMES = tuple(PROFILES)

EMBEDDINGS_SUFFIX = "+embeddings"
"""Appended to a profile's name: the profile with simulated identity embeddings on."""


def resolve_profile(profile: str | NoiseProfile) -> NoiseProfile:
    """The profile named ``profile``, or ``profile`` itself.

    ``"<name>+embeddings"``: the named profile with identity embeddings on.

    Raises
    ------
    ConfigError
        For an unknown name, listing the allowed ones.
    """
    if isinstance(profile, NoiseProfile):
        return profile
    base = profile.removesuffix(EMBEDDINGS_SUFFIX) if isinstance(profile, str) else profile
    if base not in PROFILES:
        raise ConfigError(
            f"profile: unknown {profile!r} (allowed: {', '.join(PROFILE_NAMES)}), "
            f"each optionally with {EMBEDDINGS_SUFFIX!r}"
        )
    return PROFILES[base] if base == profile else PROFILES[base].with_embeddings()
