"""The people detector: one depth frame in, person detections out.

Steps, each a small component with its settings in :class:`~openptrack_py.config.DetectorConfig`:

1. **cloud** — every ``sampling_factor``-th pixel back-projected through the intrinsics
   (optical frame), invalid and far (``max_distance_m``, by sensor type) readings dropped;
2. **ground** — the floor plane (:mod:`.ground`): estimated, calibrated or both;
3. **band** — points whose height above the floor lies in the preset's band;
4. **background** — optional removal of the learned static scene (:mod:`.background`);
5. **downsample** — one point per voxel of ``voxel_size_m / 2``;
6. **cluster** — floor-grid components split at heads (:mod:`.clustering`);
7. **describe** — position, height, distance, image box and colour signature per blob
   (:mod:`.appearance`: hue bins, then dark, grey and light bins);
8. **hog** — optional HOG check on the colour or infrared image (:mod:`.hog`).

Positions: the mean of a blob's head points on the floor, pushed away from the sensor
by ``surface_offset_m`` times the sine of the ray's angle from the vertical (a camera
that sees a person from the side sees the near surface of the body, not its centre; one
that looks straight down sees the top of the head, which is the centre:
:func:`surface_push`), at half the blob's height (like PCL's ``tcenter``). They are
reported in the world frame through the sensor's pose when it has one, else in a
floor-aligned frame under the sensor (x forward along the floor, y left, z up;
``frame_id`` = the sensor id).

Confidence (documented scale, ``[0, 1]``): without the HOG check, a blob that passes
every test scores ``0.55 + 0.4 * min(1, points / (4 * min_points))`` — more support,
more confidence. With the HOG check, that score and ``1 / (1 + exp(-2 * margin))`` are
mixed with ``hog.weight``; blobs with a margin below ``hog.min_margin`` are dropped.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from openptrack_py.config import DetectorConfig
from openptrack_py.detection.appearance import colour_signatures, signature_length
from openptrack_py.detection.background import BackgroundModel, voxel_keys
from openptrack_py.detection.clustering import Blobs, HeadClusterer
from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.detection.ground import GroundPlane, GroundTracker
from openptrack_py.geometry import apply, invert
from openptrack_py.messages.detection import Detection, DetectionBatch
from openptrack_py.sensor_types import SENSOR_TYPES

STAGES = ("cloud", "ground", "band", "background", "downsample", "cluster", "describe", "hog")
"""Names of the timed stages, in order."""

RANGE_CUT_M = 0.2
"""Blobs with points this close to ``max_distance_m`` are cut by the depth limit: dropped."""

# Corners of a blob's standing box: x sign, y sign, and whether at the blob's top.
_BOX_CORNERS = [(sx, sy, top) for sx in (-1, 1) for sy in (-1, 1) for top in (False, True)]


@dataclass(frozen=True, slots=True)
class PersonDetection:
    """One detected person, with more detail than goes on the wire.

    Parameters
    ----------
    position : tuple of float
        ``x, y, z`` in the result's frame (z = half the height).
    sensor_position : tuple of float
        The same point in the camera's optical frame.
    height : float
        Top of the blob above the floor, metres.
    confidence : float
        On ``[0, 1]`` (see the module notes).
    distance : float
        Range from the sensor, metres.
    bbox : tuple of int
        Image box ``(u, v, width, height)`` in full-resolution pixels.
    appearance : tuple of int
        Colour signature (:func:`~openptrack_py.detection.appearance.colour_signatures`:
        hue bins, then dark, grey and light); empty without colour.
    points : int
        Points supporting the blob (after down-sampling).
    hog_margin : float or None
        SVM margin when the HOG check ran.
    """

    position: tuple[float, float, float]
    sensor_position: tuple[float, float, float]
    height: float
    confidence: float
    distance: float
    bbox: tuple[int, int, int, int]
    appearance: tuple[int, ...]
    points: int
    hog_margin: float | None = None

    def to_detection(self) -> Detection:
        """The wire form."""
        x, y, z = self.position
        return Detection(
            x=x,
            y=y,
            z=z,
            height=self.height,
            confidence=self.confidence,
            distance=self.distance,
            bbox=self.bbox,
            appearance=self.appearance or None,
        )


@dataclass(frozen=True, slots=True)
class DetectionResult:
    """What the detector made of one frame.

    Parameters
    ----------
    detections : tuple of PersonDetection
        People found.
    frame_id : str
        Frame of the positions: ``world`` or the sensor id (floor-aligned sensor frame).
    ground : GroundPlane or None
        Floor used (None when not found yet: no detections then).
    timings : dict of str to float
        Seconds per stage.
    status : str
        ``ok``, ``no-ground``, ``learning-background`` or ``empty``.
    hog : str
        ``off``, ``color``, ``ir`` or ``dark`` (colour check skipped for luminance).
    """

    detections: tuple[PersonDetection, ...]
    frame_id: str
    ground: GroundPlane | None
    timings: dict[str, float] = field(default_factory=dict)
    status: str = "ok"
    hog: str = "off"

    def to_batch(self, sensor_id: str, seq: int, stamp: float) -> DetectionBatch:
        """The DetectionBatch to publish."""
        return DetectionBatch(
            sensor_id=sensor_id,
            seq=seq,
            stamp=stamp,
            frame_id=self.frame_id,
            detections=tuple(d.to_detection() for d in self.detections),
        )


class _Rays:
    """Back-projection rays of a sub-sampled pixel grid, cached per intrinsics.

    With lens distortion the rays are undistorted once here, so that detection costs
    the same per frame.
    """

    def __init__(self, intrinsics: Intrinsics, step: int) -> None:
        k = intrinsics
        self.key = (k, step)
        self.u = np.arange(0, k.width, step)
        self.v = np.arange(0, k.height, step)
        shape = (len(self.v), len(self.u))
        uu, vv = np.meshgrid(self.u, self.v)
        # flat per-pixel tables: x/z and y/z of each ray, and its pixel coordinates
        self.partial = False
        if k.has_lens:
            x, y = k.rays(uu.ravel(), vv.ravel())
            self.x, self.y = x.astype(np.float32), y.astype(np.float32)
            self.partial = not bool(np.isfinite(self.x).all())
        else:
            x = ((self.u - k.cx) / k.fx).astype(np.float32)
            y = ((self.v - k.cy) / k.fy).astype(np.float32)
            self.x = np.broadcast_to(x[None, :], shape).ravel()
            self.y = np.broadcast_to(y[:, None], shape).ravel()
        self.pixels = np.column_stack([uu.ravel(), vv.ravel()])


def surface_push(offset_m: float, reach: np.ndarray, drop: np.ndarray) -> np.ndarray:
    """How far to push each head away from the sensor, along the floor.

    Parameters
    ----------
    offset_m : float
        The push for a person seen from the side (``surface_offset_m``).
    reach : ndarray
        Horizontal distance from the sensor's foot to each head, metres.
    drop : ndarray
        How far below the sensor each head's top is, metres (clipped at 0: a head
        level with or above the sensor is seen from the side).
    """
    return offset_m * np.sin(np.arctan2(reach, np.maximum(drop, 0.0)))


class PeopleDetector:
    """Detects people in depth frames of one sensor.

    Parameters
    ----------
    config : DetectorConfig
        Settings.
    world_from_camera : ndarray, optional
        4x4 sensor pose (optical frame to world). Without it, positions are reported in
        a floor-aligned frame under the sensor.
    sensor_type : str, optional
        ``kinect1``, ``kinect2``, ``realsense`` or ``sr4500``: picks the type's default
        depth limit, sampling and fewest points, and the HOG image.
    frame_id : str
        ``frame_id`` of results when there is no pose.
    rate_hz : float
        Frame rate, to turn the background learning time into frames.
    rng : numpy.random.Generator, optional
        RANSAC randomness.
    """

    def __init__(
        self,
        config: DetectorConfig,
        *,
        world_from_camera: np.ndarray | None = None,
        sensor_type: str | None = None,
        frame_id: str = "sensor",
        rate_hz: float = 30.0,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.config = config
        self.world_from_camera = world_from_camera
        self.sensor_type = sensor_type
        self.frame_id = "world" if world_from_camera is not None else frame_id
        self.max_distance_m = config.max_distance_for(sensor_type)
        calibrated = (
            GroundPlane.from_world_pose(world_from_camera)
            if world_from_camera is not None
            else None
        )
        self.ground = GroundTracker(config.ground, calibrated, rng)
        self.clusterer = HeadClusterer(
            cell_m=config.voxel_size_m,
            heads_minimum_distance_m=config.heads_minimum_distance_m,
            min_top_m=config.top_minimum,
            max_height_m=config.band[1],
            min_points=config.min_points_for(sensor_type),
            min_size_m=config.min_size_m,
            max_size_m=config.max_size_m,
            min_area_m2=config.min_area_m2,
            max_area_m2=config.max_area_m2,
        )
        bg = config.background
        self.background = (
            BackgroundModel(bg.resolution_m, max(1, round(bg.seconds * rate_hz)))
            if bg.enabled
            else None
        )
        self._hog = None
        if config.hog.enabled:
            from openptrack_py.detection.hog import HogVerifier

            self._hog = HogVerifier()
        self._rays: _Rays | None = None

    def set_pose(self, world_from_camera: np.ndarray) -> None:
        """Use a new sensor pose from the next frame on (a calibration update).

        The floor implied by the pose becomes the calibrated floor; a ``fixed`` plane
        from the configuration stays.
        """
        self.world_from_camera = np.asarray(world_from_camera, dtype=float)
        self.frame_id = "world"
        self.ground.set_calibrated(GroundPlane.from_world_pose(self.world_from_camera))

    # ------------------------------------------------------------------ steps

    def _cloud(self, frame: Frame) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Optical-frame points, their pixel coordinates and colours."""
        max_z = self.max_distance_m
        if frame.depth is None:
            pts = np.asarray(frame.points, dtype=np.float32).reshape(-1, 3)
            ok = np.isfinite(pts).all(axis=1) & (pts[:, 2] > 0) & (pts[:, 2] <= max_z)
            colours = None if frame.point_colors is None else np.asarray(frame.point_colors)[ok]
            return pts[ok], None, colours
        assert frame.intrinsics is not None
        step = self.config.sampling_for(self.sensor_type, frame.intrinsics.width)
        if self._rays is None or self._rays.key != (frame.intrinsics, step):
            self._rays = _Rays(frame.intrinsics, step)
        rays = self._rays
        depth = frame.depth[::step, ::step].ravel()
        with np.errstate(invalid="ignore"):
            ok = (depth > 0) & (depth <= max_z)  # NaN compares False
        if rays.partial:  # pixels whose lens cannot be inverted see nothing
            ok &= np.isfinite(rays.x)
        z = depth[ok].astype(np.float32)
        pts = np.column_stack([rays.x[ok] * z, rays.y[ok] * z, z])
        pixels = np.compress(ok, rays.pixels, axis=0)
        colours = None
        if frame.color is not None:
            colours = np.compress(ok, frame.color[::step, ::step].reshape(-1, 3), axis=0)
        return pts, pixels, colours

    # ------------------------------------------------------------------ detect

    def detect(self, frame: Frame) -> DetectionResult:
        """Detect the people in one frame."""
        cfg = self.config
        timings: dict[str, float] = {}

        @contextmanager
        def stage(name: str) -> Iterator[None]:
            t0 = time.perf_counter()
            yield
            timings[name] = time.perf_counter() - t0

        with stage("cloud"):
            pts, pixels, colours = self._cloud(frame)
        with stage("ground"):
            plane = self.ground.update(pts) if len(pts) else self.ground.plane
        if plane is None:
            return DetectionResult((), self.frame_id, None, timings, "no-ground")
        with stage("band"):
            low, high = cfg.band
            h = plane.height(pts)
            band = (h >= low) & (h <= high)
            floor_from_camera = plane.ground_from_camera()
            sel = np.flatnonzero(band)
            floor_pts = apply(floor_from_camera.astype(np.float32), pts[sel]).astype(np.float32)
        if self.background is not None:
            with stage("background"):
                if self.background.learning:
                    self.background.learn(floor_pts)
                    return DetectionResult(
                        (), self.frame_id, plane, timings, "learning-background"
                    )
                keep = self.background.foreground(floor_pts)
                sel, floor_pts = sel[keep], floor_pts[keep]
        with stage("downsample"):
            keys = voxel_keys(floor_pts, cfg.voxel_size_m / 2)
            _, first = np.unique(keys, return_index=True)
            sel, floor_pts = sel[first], floor_pts[first]
        with stage("cluster"):
            blobs = self.clusterer.cluster(floor_pts)
            if len(blobs):
                # Blobs reaching the depth limit were cut by it (walls, far furniture).
                far = np.zeros(len(blobs))
                member = blobs.labels >= 0
                np.maximum.at(far, blobs.labels[member], pts[sel[member], 2])
                keep = far < self.max_distance_m - RANGE_CUT_M
                if pixels is not None:
                    keep &= ~self._top_on_border(blobs, floor_pts, pixels[sel])
                blobs = blobs.select(keep)
        if len(blobs) == 0:
            return DetectionResult((), self.frame_id, plane, timings, "empty")
        with stage("describe"):
            people = self._describe(frame, floor_from_camera, blobs, sel, pixels, colours)
        hog_mode = "off"
        if self._hog is not None:
            with stage("hog"):
                people, hog_mode = self._hog_check(frame, people)
        return DetectionResult(tuple(people), self.frame_id, plane, timings, "ok", hog_mode)

    @staticmethod
    def _top_on_border(blobs: Blobs, floor_pts: np.ndarray, pixels: np.ndarray) -> np.ndarray:
        """Per blob: whether its highest point lies in the image's top row.

        Then its real top is out of view — a wall cut by the top of the image looks like
        a head there — and its height cannot be measured: such blobs are dropped.
        """
        member = np.flatnonzero(blobs.labels >= 0)
        labels = blobs.labels[member]
        best = np.full(len(blobs), -1)
        order = np.argsort(floor_pts[member, 2])  # ascending: the last write is the top
        best[labels[order]] = member[order]
        return pixels[best, 1] == 0

    def _describe(
        self,
        frame: Frame,
        floor_from_camera: np.ndarray,
        blobs: Blobs,
        sel: np.ndarray,
        pixels: np.ndarray | None,
        colours: np.ndarray | None,
    ) -> list[PersonDetection]:
        cfg = self.config
        k = len(blobs)
        xy = blobs.head_xy.copy()
        # the floor frame's origin is the sensor's foot: push away from it
        reach = np.linalg.norm(xy, axis=1)
        push = surface_push(cfg.surface_offset_m, reach, floor_from_camera[2, 3] - blobs.top)
        xy += (push / np.maximum(reach, 1e-6))[:, None] * xy
        floor = np.column_stack([xy, blobs.top / 2])
        camera_from_floor = invert(floor_from_camera)
        optical = apply(camera_from_floor, floor)
        world = (
            apply(self.world_from_camera, optical) if self.world_from_camera is not None else floor
        )
        distance = np.linalg.norm(optical, axis=1)
        support = np.minimum(1.0, blobs.points / (4.0 * self.clusterer.min_points))
        confidence = 0.55 + 0.4 * support
        boxes = self._boxes(frame, camera_from_floor, xy, blobs)
        looks = np.zeros((k, signature_length(cfg.appearance_bins)), dtype=np.uint8)
        if colours is not None:
            labels = blobs.labels
            looks = colour_signatures(colours[sel], labels, k, bins=cfg.appearance_bins)
        return [
            PersonDetection(
                position=tuple(float(v) for v in world[i]),
                sensor_position=tuple(float(v) for v in optical[i]),
                height=float(blobs.top[i]),
                confidence=float(confidence[i]),
                distance=float(distance[i]),
                bbox=boxes[i],
                appearance=tuple(int(v) for v in looks[i]) if colours is not None else (),
                points=int(blobs.points[i]),
            )
            for i in range(k)
        ]

    def _boxes(
        self,
        frame: Frame,
        camera_from_floor: np.ndarray,
        xy: np.ndarray,
        blobs: Blobs,
    ) -> list[tuple[int, int, int, int]]:
        """Image boxes of standing boxes from the floor to each blob's top."""
        k = frame.intrinsics
        if k is None:
            return [(0, 0, 0, 0)] * len(xy)
        half = np.maximum(blobs.length, 0.3) / 2
        corners = np.empty((len(xy), 8, 3))
        for c, (sx, sy, top) in enumerate(_BOX_CORNERS):
            corners[:, c, 0] = xy[:, 0] + sx * half
            corners[:, c, 1] = xy[:, 1] + sy * half
            corners[:, c, 2] = blobs.top if top else 0.0
        cam = apply(camera_from_floor, corners)
        cam[..., 2] = np.maximum(cam[..., 2], 1e-3)
        u, v = k.pixels(cam)
        u, v = np.clip(u, 0, k.width - 1), np.clip(v, 0, k.height - 1)
        u0, v0 = u.min(axis=1).astype(int), v.min(axis=1).astype(int)
        u1, v1 = u.max(axis=1).astype(int), v.max(axis=1).astype(int)
        return [tuple(box) for box in np.column_stack([u0, v0, u1 - u0, v1 - v0]).tolist()]

    def _hog_check(
        self, frame: Frame, people: list[PersonDetection]
    ) -> tuple[list[PersonDetection], str]:
        """Score boxes with HOG; drop low margins; blend confidences."""
        from openptrack_py.detection.hog import equalised_ir, luminance, margin_to_confidence

        hog_cfg = self.config.hog
        kind = SENSOR_TYPES.get(self.sensor_type or "")
        use_ir = hog_cfg.image == "ir" or (
            hog_cfg.image == "auto" and kind is not None and kind.time_of_flight
        )
        if use_ir and frame.intensity is not None:
            gray, mode = equalised_ir(frame.intensity), "ir"
        elif frame.color is not None:
            if luminance(frame.color) < hog_cfg.min_luminance:
                return people, "dark"
            gray, mode = self._hog.gray(frame.color), "color"  # type: ignore[union-attr]
        else:
            return people, "off"
        margins = self._hog.score(gray, [p.bbox for p in people])  # type: ignore[union-attr]
        hog_conf = margin_to_confidence(margins)
        w = hog_cfg.weight
        kept = [
            dataclasses.replace(
                p, confidence=float((1 - w) * p.confidence + w * c), hog_margin=float(m)
            )
            for p, m, c in zip(people, margins, hog_conf, strict=True)
            if m >= hog_cfg.min_margin
        ]
        return kept, mode
