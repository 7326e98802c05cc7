"""The calibration file: where every sensor of a network stands, in one YAML.

One file per network (or per sensor: a file may hold any subset of the sensors)::

    version: 1
    frame: world
    sensors:
      k2_a:
        rotation: [[-0.0, -0.34, 0.94], [-1.0, 0.0, -0.0], [0.0, -0.94, -0.34]]
        translation: [0.0, 0.0, 2.5]
        clock_offset_s: 0.012
        method: checkerboard
        date: 2026-11-25T10:00:00Z
        residuals: {reprojection_px: 0.21, views: 38}
        intrinsics: {width: 512, height: 424, fx: 365.0, fy: 365.0, cx: 256.0, cy: 212.0}
        floor: [0.0, -0.94, -0.34, 2.5]
      k2_b:
        pose: {x: 6.0, y: 4.0, z: 2.5, yaw_deg: 225.0, pitch_deg: 20.0}

Per sensor, the pose is either ``rotation`` and ``translation`` (the optical frame's
axes and origin in world coordinates: what calibration writes) or ``pose`` (position,
heading, tilt and roll: what a person types). A rotation must be orthonormal with
determinant +1; every error names its field (``sensors.k2_a.rotation``).
``clock_offset_s`` is the sensor clock minus the reference clock: stamps are corrected
by subtracting it. ``floor`` is the floor plane ``a, b, c, d`` in the sensor's optical
frame. ``residuals`` holds the figures of merit of the method that wrote the entry.

:func:`load_calibration` reads and validates a file; :func:`save_calibration` writes
one atomically (a reader never sees half a file); :func:`network_calibration` gathers
the entries a network's sensors use and rejects entries for sensors it does not have.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Mapping
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np
import orjson
import yaml
from pydantic import Field, model_validator

from openptrack_py.config.base import Name, StrictModel
from openptrack_py.config.loading import read_yaml, validate_config
from openptrack_py.config.sensors import Pose
from openptrack_py.detection.frame import Intrinsics
from openptrack_py.detection.lens import LENS_TERMS
from openptrack_py.errors import CalibrationError, ConfigError
from openptrack_py.geometry import pose_from_transform, world_from_optical

if TYPE_CHECKING:
    from openptrack_py.config import NetworkConfig

ORTHONORMAL_TOLERANCE = 1e-3
"""Largest entry of ``|R^T R - I|`` accepted: rotations written with six decimals pass,
a hand-edited matrix with a typo does not."""

Method = Literal["manual", "checkerboard", "walk", "refinement", "floor"]
"""How an entry was obtained."""

Vector3 = tuple[float, float, float]


class CameraIntrinsics(StrictModel):
    """Pinhole intrinsics of the depth image, when calibrated.

    Parameters
    ----------
    width, height : int
        Image size, pixels.
    fx, fy : float
        Focal lengths, pixels.
    cx, cy : float
        Principal point, pixels.
    distortion : tuple of float
        OpenCV distortion coefficients ``k1, k2, p1, p2, k3`` (empty: none; OpenCV's
        longer models are accepted when their further terms are 0).
    """

    width: int = Field(gt=0, le=20000)
    height: int = Field(gt=0, le=20000)
    fx: float = Field(gt=0.0)
    fy: float = Field(gt=0.0)
    cx: float
    cy: float
    distortion: tuple[float, ...] = Field(default=(), max_length=14)


class SensorCalibration(StrictModel):
    """One sensor's calibration entry.

    Parameters
    ----------
    rotation : 3x3 tuple of float, optional
        Rows of the rotation taking optical-frame vectors to the world frame.
    translation : tuple of float, optional
        The optical centre in the world frame, metres.
    pose : Pose, optional
        The same as position, heading, tilt and roll (instead of the two above).
    clock_offset_s : float
        Sensor clock minus reference clock, seconds.
    intrinsics : CameraIntrinsics, optional
        Calibrated intrinsics.
    floor : tuple of float, optional
        Floor plane ``a, b, c, d`` in the optical frame.
    residuals : dict of str to int or float
        Figures of merit of the method (e.g. ``reprojection_px``, ``disagreement_m``).
    method : {"manual", "checkerboard", "walk", "refinement", "floor"}
        How the entry was obtained.
    date : datetime, optional
        When.
    """

    rotation: tuple[Vector3, Vector3, Vector3] | None = None
    translation: Vector3 | None = None
    pose: Pose | None = None
    clock_offset_s: float = Field(0.0, ge=-3600.0, le=3600.0)
    intrinsics: CameraIntrinsics | None = None
    floor: tuple[float, float, float, float] | None = None
    residuals: dict[str, int | float] = Field(default_factory=dict)
    method: Method = "manual"
    date: datetime | None = None

    @model_validator(mode="after")
    def _one_pose(self) -> SensorCalibration:
        matrix = self.rotation is not None or self.translation is not None
        if matrix and self.pose is not None:
            raise ValueError("give either 'pose' or 'rotation' and 'translation', not both")
        if not matrix and self.pose is None:
            raise ValueError("needs 'rotation' and 'translation' (or 'pose')")
        if matrix and (self.rotation is None or self.translation is None):
            missing = "translation" if self.translation is None else "rotation"
            raise ValueError(f"'{missing}' is missing ('rotation' needs 'translation')")
        if self.rotation is not None:
            check_rotation(np.asarray(self.rotation, dtype=float))
        if self.floor is not None and math.hypot(*self.floor[:3]) < 1e-9:
            raise ValueError("'floor': the plane's normal (a, b, c) is zero")
        return self

    def world_from_optical(self) -> np.ndarray:
        """4x4 transform taking optical-frame points to the world frame."""
        if self.pose is not None:
            return world_from_optical(self.pose)
        out = np.eye(4)
        out[:3, :3] = np.asarray(self.rotation, dtype=float)
        out[:3, 3] = np.asarray(self.translation, dtype=float)
        return out

    def camera(self) -> Intrinsics | None:
        """The calibrated camera model the detector uses (``None`` if the entry has none).

        Its pinhole and lens distortion ``k1, k2, p1, p2, k3`` (a camera's factory terms,
        as its driver or another calibration tool writes them, or this project's).

        Raises
        ------
        ConfigError
            If the entry's distortion has terms of OpenCV's longer models (rational
            ``k4``-``k6``, thin prism ``s1``-``s4``, tilt) that are not 0: the detector
            does not model them, and dropping them would misplace pixels silently.
        """
        k = self.intrinsics
        if k is None:
            return None
        if any(v != 0.0 for v in k.distortion[len(LENS_TERMS) :]):
            raise ConfigError(
                f"intrinsics.distortion: the detector models {', '.join(LENS_TERMS)} only; "
                "the rational, thin-prism and tilt terms after them must be 0 (received "
                f"{list(k.distortion)}): calibrate with OpenCV's 5-term model, or with "
                "'openptrack calibrate checkerboard --refine-intrinsics --lens full'"
            )
        pinhole = Intrinsics(k.width, k.height, k.fx, k.fy, k.cx, k.cy)
        return pinhole.with_distortion(k.distortion[: len(LENS_TERMS)])

    def as_pose(self) -> Pose:
        """The pose as position, heading, tilt and roll."""
        return (
            self.pose if self.pose is not None else pose_from_transform(self.world_from_optical())
        )

    @classmethod
    def from_transform(cls, world_from_camera: np.ndarray, **fields: object) -> SensorCalibration:
        """An entry for a 4x4 ``world_from_optical`` transform (rotation re-orthonormalised).

        Parameters
        ----------
        world_from_camera : ndarray
            The transform.
        **fields
            Other entry fields (``method``, ``residuals``, ``clock_offset_s``, ...).
        """
        u, _, vt = np.linalg.svd(np.asarray(world_from_camera, dtype=float)[:3, :3])
        rot = u @ vt
        rows = tuple(tuple(round(float(v), 9) for v in row) for row in rot)
        trans = tuple(round(float(v), 6) for v in np.asarray(world_from_camera)[:3, 3])
        return cls(rotation=rows, translation=trans, **fields)  # type: ignore[arg-type]


class CalibrationFile(StrictModel):
    """A calibration file.

    Parameters
    ----------
    version : int
        Format version (1).
    frame : str
        The frame the poses are in (``world``).
    sensors : dict of str to SensorCalibration
        Entries by sensor id.
    """

    version: Literal[1] = 1
    frame: Name = "world"
    sensors: dict[Name, SensorCalibration] = Field(default_factory=dict)

    def replaced(self, entries: Mapping[str, SensorCalibration]) -> CalibrationFile:
        """A copy with ``entries`` added or replacing the sensors' old ones.

        A walk's entry (method ``walk`` or ``refinement``) measures the pose and clock
        only: it keeps the old entry's intrinsics, through which its detections were
        made. Any other entry replaces the old one whole.
        """
        merged = dict(self.sensors)
        for sensor_id, entry in entries.items():
            old = self.sensors.get(sensor_id)
            keep = entry.method in ("walk", "refinement") and entry.intrinsics is None
            if keep and old is not None and old.intrinsics is not None:
                entry = entry.model_copy(update={"intrinsics": old.intrinsics})
            merged[sensor_id] = entry
        return self.model_copy(update={"sensors": merged})


def check_rotation(rotation: np.ndarray) -> None:
    """Raise ``ValueError`` unless ``rotation`` is a proper 3x3 rotation.

    Raises
    ------
    ValueError
        Naming how far from orthonormal it is, or a negative determinant (a mirror).
    """
    error = float(np.abs(rotation.T @ rotation - np.eye(3)).max())
    if not math.isfinite(error) or error > ORTHONORMAL_TOLERANCE:
        raise ValueError(
            f"'rotation' is not orthonormal (largest entry of |R^T R - I| is {error:.3g}, "
            f"allowed {ORTHONORMAL_TOLERANCE:g})"
        )
    det = float(np.linalg.det(rotation))
    if det < 0:
        raise ValueError(f"'rotation' is a reflection (determinant {det:.3f}, must be +1)")


def parse_calibration(data: object, source: str = "calibration") -> CalibrationFile:
    """Validate a calibration mapping.

    Raises
    ------
    CalibrationError
        Naming every bad field (``sensors.k2_a.rotation: ...``).
    """
    try:
        return validate_config(CalibrationFile, data, source)
    except ConfigError as exc:
        raise CalibrationError(
            str(exc).replace("invalid configuration", "invalid calibration")
        ) from None


def load_calibration(path: str | Path) -> CalibrationFile:
    """Read and validate a calibration file.

    Raises
    ------
    CalibrationError
        If it is missing, not YAML or invalid; the message names the file and field.
    """
    try:
        data = read_yaml(path)
    except ConfigError as exc:
        raise CalibrationError(str(exc)) from None
    return parse_calibration(data, str(path))


def calibration_yaml(calibration: CalibrationFile) -> str:
    """The file's text: a header line, then the entries (unset fields left out)."""
    data = calibration.model_dump(mode="json", exclude_none=True)
    for entry in data["sensors"].values():
        if not entry.get("residuals"):
            entry.pop("residuals", None)
    body = yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=100)
    return "# openptrack_py calibration (see 'openptrack calibrate --help')\n" + body


def save_calibration(path: str | Path, calibration: CalibrationFile) -> None:
    """Write a calibration file atomically (temporary file, then rename).

    Raises
    ------
    CalibrationError
        If the file cannot be written.
    """
    path = Path(path)
    text = calibration_yaml(calibration)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except OSError as exc:
        raise CalibrationError(f"{path}: cannot write ({exc.strerror or exc})") from None


def entry_payload(sensor_id: str, entry: SensorCalibration, frame: str = "world") -> bytes:
    """One entry as served over the bus (JSON)."""
    data = entry.model_dump(mode="json", exclude_none=True)
    return orjson.dumps({"sensor_id": sensor_id, "frame": frame, "entry": data})


def parse_entry_payload(payload: bytes) -> tuple[str, SensorCalibration]:
    """The sensor id and entry of a payload from :func:`entry_payload`.

    Raises
    ------
    CalibrationError
        If the bytes are not a valid entry.
    """
    try:
        data = orjson.loads(payload)
    except orjson.JSONDecodeError as exc:
        raise CalibrationError(f"calibration message: not JSON ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("sensor_id"), str):
        raise CalibrationError("calibration message: needs 'sensor_id' and 'entry'")
    sensor_id = data["sensor_id"]
    parsed = parse_calibration({"sensors": {sensor_id: data.get("entry")}}, "calibration message")
    return sensor_id, parsed.sensors[sensor_id]


def sensor_calibration_paths(network: NetworkConfig) -> dict[str, Path]:
    """The calibration file each sensor uses: its own, else the network's."""
    out = {}
    for sensor in network.sensors:
        path = sensor.calibration or network.calibration
        if path is not None:
            out[sensor.id] = Path(path)
    return out


def network_calibration(network: NetworkConfig) -> dict[str, SensorCalibration]:
    """Every calibrated sensor's entry, from the files the network names.

    Raises
    ------
    CalibrationError
        If a file is invalid, names a sensor the network does not have, or lacks a
        sensor that points to it.
    """
    known = {s.id for s in network.sensors}
    files: dict[Path, CalibrationFile] = {}
    out: dict[str, SensorCalibration] = {}
    for sensor_id, path in sensor_calibration_paths(network).items():
        if path not in files:
            files[path] = load_calibration(path)
            unknown = sorted(set(files[path].sensors) - known)
            if unknown:
                raise CalibrationError(
                    f"{path}: unknown sensor {', '.join(repr(u) for u in unknown)} "
                    f"(the network's sensors: {', '.join(sorted(known))})"
                )
        entry = files[path].sensors.get(sensor_id)
        if entry is None:
            if network.sensor(sensor_id).calibration is not None:
                raise CalibrationError(
                    f"sensors.{sensor_id}.calibration: {path} has no entry for {sensor_id!r} "
                    f"(it has: {', '.join(sorted(files[path].sensors)) or 'none'})"
                )
            continue
        out[sensor_id] = entry
    return out


def believed_poses(network: NetworkConfig) -> dict[str, np.ndarray]:
    """Each sensor's ``world_from_optical`` as the pipeline believes it.

    The calibration entry when the sensor has one, else its ``pose``; sensors with
    neither are left out (they report in their own floor frame).

    Raises
    ------
    CalibrationError
        As :func:`network_calibration`.
    """
    entries = network_calibration(network)
    out = {}
    for sensor in network.sensors:
        if sensor.id in entries:
            out[sensor.id] = entries[sensor.id].world_from_optical()
        elif sensor.pose is not None:
            out[sensor.id] = world_from_optical(sensor.pose)
    return out
