"""Person detections from one sensor frame, checked when they are built.

A :class:`Detection` or :class:`DetectionBatch` that exists is valid: finite numbers in
the ranges the wire decoder accepts, names the wire allows, bounded sizes. Building one
with a bad field raises :class:`~openptrack_py.errors.WireFormatError` (a
``ValueError``) naming the field in the decoder's words, e.g.
``Detection.confidence: expected a number in [0, 1], got 1.5``, so that a producer's
bug shows where it happens instead of at the receiving end.
"""

from __future__ import annotations

import math
import numbers
from collections import defaultdict
from dataclasses import dataclass
from typing import Any

from openptrack_py.errors import WireFormatError
from openptrack_py.messages.fields import (
    MAX_APPEARANCE_BINS,
    MAX_COORD_M,
    MAX_FACE_DIMS,
    MAX_HEIGHT_M,
    MAX_INT,
    MAX_ITEMS,
    MAX_NAME_LEN,
    MAX_STAMP_S,
    NAME_RE,
    fail,
)

_PLAIN: defaultdict[type, bool] = defaultdict(bool, {float: True, int: True})
"""Types that need no closer look (bool, numpy scalars... go the slow way)."""
_INT_ONLY = {int}
_BBOX_LIMIT = 1 << 20
"""Largest image coordinate or box side, pixels (as on the wire)."""


def _number(path: str, value: Any, lo: float, hi: float) -> None:
    """Raise unless ``value`` is a real number (not a bool) in ``[lo, hi]``."""
    exact = type(value) is float or type(value) is int
    if not exact and (isinstance(value, bool) or not isinstance(value, numbers.Real)):
        raise fail(path, "a number", value)
    if not lo <= value <= hi:  # also rejects NaN
        if not math.isfinite(value):
            raise fail(path, "a finite number", value)
        raise fail(path, f"a number in [{lo:g}, {hi:g}]", value)


def _integer(path: str, value: Any, lo: int, hi: int) -> None:
    """Raise unless ``value`` is an integer (not a bool) in ``[lo, hi]``."""
    if type(value) is not int and (
        isinstance(value, bool) or not isinstance(value, numbers.Integral)
    ):
        raise fail(path, "an integer", value)
    if not lo <= value <= hi:
        raise fail(path, f"an integer in [{lo}, {hi}]", value)


def _name(path: str, value: Any) -> None:
    """Raise unless ``value`` is a sensor or frame name the wire accepts."""
    if (
        type(value) is not str
        or not 0 < len(value) <= MAX_NAME_LEN
        or not NAME_RE.fullmatch(value)
    ):
        raise fail(path, f"a name of 1-{MAX_NAME_LEN} characters from [A-Za-z0-9_.-]", value)


def _items(path: str, value: Any, max_len: int) -> None:
    """Raise unless ``value`` is a tuple of at most ``max_len`` items."""
    if type(value) is not tuple:
        raise fail(path, "a tuple", value)
    if len(value) > max_len:
        raise WireFormatError(f"{path}: at most {max_len} items allowed, got {len(value)}")


@dataclass(frozen=True, slots=True)
class Detection:
    """One person detected in one sensor frame.

    Parameters
    ----------
    x, y, z : float
        Centroid in metres, in the batch's ``frame_id`` (``world``: x, y on the floor,
        z up); each within 10 km of the origin.
    height : float
        Top of the person above the floor, metres, in ``[0, 10]``.
    confidence : float
        Detector confidence in ``[0, 1]``: 0 = certainly not a person, 1 = certainly a
        person. Detectors map their native scores (HOG margins, cluster shape scores)
        onto this scale.
    distance : float
        Range from the sensor to the centroid, metres, ``>= 0``.
    bbox : tuple of int, optional
        Image box ``(u, v, width, height)`` in pixels of the sensor's depth image.
    appearance : tuple of int, optional
        Appearance signature: a small quantised colour histogram (at most 256 bins, each
        0-255).
    face : tuple of float, optional
        Face embedding (at most 1024 finite numbers), when a face recogniser ran.
    face_confidence : float, optional
        How far the embedding can be trusted, in ``[0, 1]`` (e.g. from the face's angle
        and distance to the sensor); only with ``face``.

    Raises
    ------
    WireFormatError
        Naming the first field that is not a number, not finite, out of range or too
        large.
    """

    x: float
    y: float
    z: float
    height: float
    confidence: float
    distance: float
    bbox: tuple[int, int, int, int] | None = None
    appearance: tuple[int, ...] | None = None
    face: tuple[float, ...] | None = None
    face_confidence: float | None = None

    def __post_init__(self) -> None:
        x, y, z, height, conf, dist = (
            self.x,
            self.y,
            self.z,
            self.height,
            self.confidence,
            self.distance,
        )
        # Fast path (every number a plain float or int, in range); else find the culprit.
        if not (
            _PLAIN[type(x)]
            and _PLAIN[type(y)]
            and _PLAIN[type(z)]
            and _PLAIN[type(height)]
            and _PLAIN[type(conf)]
            and _PLAIN[type(dist)]
            and -MAX_COORD_M <= x <= MAX_COORD_M
            and -MAX_COORD_M <= y <= MAX_COORD_M
            and -MAX_COORD_M <= z <= MAX_COORD_M
            and 0.0 <= height <= MAX_HEIGHT_M
            and 0.0 <= conf <= 1.0
            and 0.0 <= dist <= MAX_COORD_M
        ):
            self._check_numbers()
        if self.bbox is not None:
            self._check_bbox(self.bbox)
        if self.appearance is not None:
            self._check_appearance(self.appearance)
        if self.face is not None:
            self._check_face(self.face)
        if self.face_confidence is not None:
            _number("Detection.face_confidence", self.face_confidence, 0.0, 1.0)
            if self.face is None:
                raise fail(
                    "Detection.face_confidence",
                    "a value only alongside face",
                    self.face_confidence,
                )

    def _check_numbers(self) -> None:
        _number("Detection.x", self.x, -MAX_COORD_M, MAX_COORD_M)
        _number("Detection.y", self.y, -MAX_COORD_M, MAX_COORD_M)
        _number("Detection.z", self.z, -MAX_COORD_M, MAX_COORD_M)
        _number("Detection.height", self.height, 0.0, MAX_HEIGHT_M)
        _number("Detection.confidence", self.confidence, 0.0, 1.0)
        _number("Detection.distance", self.distance, 0.0, MAX_COORD_M)

    @staticmethod
    def _check_appearance(appearance: Any) -> None:
        if (
            type(appearance) is tuple
            and 0 < len(appearance) <= MAX_APPEARANCE_BINS
            and set(map(type, appearance)) == _INT_ONLY
            and min(appearance) >= 0
            and max(appearance) <= 255
        ):
            return
        _items("Detection.appearance", appearance, MAX_APPEARANCE_BINS)
        for i, v in enumerate(appearance):
            _integer(f"Detection.appearance[{i}]", v, 0, 255)

    @staticmethod
    def _check_face(face: Any) -> None:
        _items("Detection.face", face, MAX_FACE_DIMS)
        for i, v in enumerate(face):
            _number(f"Detection.face[{i}]", v, -math.inf, math.inf)
            if not math.isfinite(v):
                raise fail(f"Detection.face[{i}]", "a finite number", v)

    @staticmethod
    def _check_bbox(bbox: Any) -> None:
        if type(bbox) is tuple and len(bbox) == 4:
            u, v, w, h = bbox
            if (
                type(u) is int
                and type(v) is int
                and type(w) is int
                and type(h) is int
                and -_BBOX_LIMIT <= u <= _BBOX_LIMIT
                and -_BBOX_LIMIT <= v <= _BBOX_LIMIT
                and 0 <= w <= _BBOX_LIMIT
                and 0 <= h <= _BBOX_LIMIT
            ):
                return
        expected = "[u, v, width, height] with width, height >= 0"
        if type(bbox) is not tuple or len(bbox) != 4:
            raise fail("Detection.bbox", expected, bbox)
        for i, v in enumerate(bbox):
            _integer(f"Detection.bbox[{i}]", v, -_BBOX_LIMIT, _BBOX_LIMIT)
        if bbox[2] < 0 or bbox[3] < 0:
            raise fail("Detection.bbox", expected, bbox)


@dataclass(frozen=True, slots=True)
class DetectionBatch:
    """Every detection of one sensor frame (possibly none).

    Parameters
    ----------
    sensor_id : str
        Identifier of the sensor, as in the network file (1-128 characters from
        ``[A-Za-z0-9_.-]``).
    seq : int
        Per-sensor frame counter, starting at 0, increasing by one per frame.
    stamp : float
        Capture time of the frame, UNIX seconds on the sensor's clock, ``>= 0``.
    frame_id : str
        ``"world"`` once the sensor is calibrated, else the sensor's own frame.
    detections : tuple of Detection
        The people seen in this frame (at most 2000).

    Raises
    ------
    WireFormatError
        Naming the first invalid field.
    """

    sensor_id: str
    seq: int
    stamp: float
    frame_id: str
    detections: tuple[Detection, ...] = ()

    def __post_init__(self) -> None:
        _name("DetectionBatch.sensor_id", self.sensor_id)
        _integer("DetectionBatch.seq", self.seq, 0, MAX_INT)
        _number("DetectionBatch.stamp", self.stamp, 0.0, MAX_STAMP_S)
        _name("DetectionBatch.frame_id", self.frame_id)
        _items("DetectionBatch.detections", self.detections, MAX_ITEMS)
        for i, d in enumerate(self.detections):
            if not isinstance(d, Detection):
                raise fail(f"DetectionBatch.detections[{i}]", "a Detection", d)
