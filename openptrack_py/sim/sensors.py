"""Detection-level sensor models: what a depth sensor's people detector would report.

For each frame a :class:`SensorModel` decides, person by person, whether the detector
would find them and where it would put them:

* **field of view and range** of the sensor type, tested on sample points of the body
  (head, shoulders, chest, hips, knees) in the sensor's optical frame;
* **line of sight**: each sample point can be hidden by another person (a vertical
  cylinder) or a piece of furniture (a box) between it and the sensor;
* **detection**: the head must be visible (detectors look for heads) and enough of the
  body; then a miss probability that grows past the type's reliable range;
* **noise**: along the viewing ray with a standard deviation ``s0 + s1*d + s2*d**2``
  (Kinect v1 grows with distance squared, time-of-flight sensors are nearly constant)
  and across it, plus height noise;
* **merges and splits**: two people closer than ``merge_distance_m`` become one
  detection at their mean; rarely one person splits into two blobs;
* **clutter**: Poisson false positives on free floor in view, with low confidence;
* **calibration error**: detections are mapped to the world with the pose the sensor
  *believes*, which may differ from its true pose;
* a **noise profile** (:mod:`~openptrack_py.sim.profiles`, ``ideal`` by default) adds
  what real detectors do beyond that: a centroid error that persists per person
  (:mod:`~openptrack_py.sim.centroid_error`), outliers, half-hidden people detected
  off-centre, confident false positives, decoys and persistent splits
  (:mod:`~openptrack_py.sim.false_positives`), a wider merge distance.

Confidence is on ``[0, 1]``; true people score roughly 0.6-0.95 depending on how much of
them is visible, clutter roughly 0.1-0.5.

Each detection carries a colour signature in the real detector's layout, from the
person's clothes as this sensor sees them (:mod:`~openptrack_py.sim.signatures`) and,
with the profile's ``embeddings`` on, a simulated identity embedding of people facing the
sensor (:mod:`~openptrack_py.sim.embeddings`). Both draw only from the sensor's own
appearance generator, never from the one behind positions, confidences, misses and
clutter, so they change none of those.

Field of view, ranges and rate are the sensor type's facts
(:mod:`openptrack_py.sensor_types`); the noise, miss, clutter and split figures per type
are the simulator's own model (:data:`SENSOR_NOISE`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from openptrack_py.geometry import world_from_optical
from openptrack_py.messages.detection import Detection
from openptrack_py.sim.centroid_error import CentroidError
from openptrack_py.sim.embeddings import FaceRecogniser, IdentityVectors
from openptrack_py.sim.false_positives import (
    Blob,
    Decoy,
    DecoySightings,
    SplitBlobs,
    TransientFalsePositives,
)
from openptrack_py.sim.height_error import HeightError
from openptrack_py.sim.profiles import (
    FALSE_POSITIVE_TYPE_FACTOR,
    IDEAL,
    NoiseProfile,
    resolve_profile,
)
from openptrack_py.sim.sensor_spec import (
    APPEARANCE_BINS,
    APPEARANCE_LENGTH,
    SENSOR_NOISE,
    SensorNoise,
    SensorSpec,
)
from openptrack_py.sim.signatures import SignatureModel
from openptrack_py.sim.visibility import SensorView, visible_lateral_offset, visible_summary
from openptrack_py.sim.world import Room, Snapshot

__all__ = [
    "APPEARANCE_BINS",
    "APPEARANCE_LENGTH",
    "SENSOR_NOISE",
    "Observation",
    "SensorModel",
    "SensorNoise",
    "SensorSpec",
]

_LEGACY_BINS = 16
"""Bins of the hue-only signature the sensor model once drew from its main generator."""


def _own_generator(rng: np.random.Generator, key: int) -> np.random.Generator:
    """A generator derived from ``rng``'s seed and ``key``.

    Neither draws from ``rng`` nor spawns from it: its stream and the children it
    spawns stay as they were.
    """
    seq = getattr(rng.bit_generator, "seed_seq", None)
    if not isinstance(seq, np.random.SeedSequence):
        return np.random.default_rng(key)
    return np.random.default_rng(
        np.random.SeedSequence(seq.entropy, spawn_key=(*seq.spawn_key, 1 << 20, key))
    )


@dataclass(frozen=True)
class Observation:
    """What one sensor reported in one frame, with the truth behind it.

    Parameters
    ----------
    detections : tuple of Detection
        World-frame detections (through the believed pose).
    person_ids : tuple of int
        Ground-truth person id behind each detection; 0 for a false detection (clutter,
        a split blob, a noise profile's false positive or decoy).
    """

    detections: tuple[Detection, ...]
    person_ids: tuple[int, ...]


class SensorModel(SensorView):
    """Turns the world's state into one sensor's detections.

    Parameters
    ----------
    spec : SensorSpec
        The sensor.
    room : Room
        The room (for furniture occlusion and clutter placement).
    rng : numpy.random.Generator
        This sensor's own randomness (the profile's mechanisms each use a generator
        spawned from it, drawn only when the mechanism is on).
    merge_distance_m : float, optional
        People closer than this (centre to centre) come out as one detection; the
        profile's ``merge_distance_m`` if omitted.
    profile : NoiseProfile or str
        The noise profile's per-frame mechanisms. Its per-sensor figures (misses,
        calibration and clock offsets, jitter, drops) are in ``spec``
        (:func:`~openptrack_py.sim.sensor_faults.draw_sensor_faults`).
    decoys : sequence of Decoy
        The scenario's static false positives; the sensor reports those it can see.
    appearance_rng : numpy.random.Generator, optional
        This sensor's own randomness for signatures and embeddings (its colour cast is
        the first draw). Derived from ``rng``'s seed, without drawing from it, if omitted.
    identities : IdentityVectors, optional
        Everyone's identity vectors, for the profile's embeddings; shared by the sensors
        of one scenario (:class:`~openptrack_py.sim.simulator.Simulator` seeds them with
        the scenario seed). Seed 0 if omitted.
    """

    def __init__(
        self,
        spec: SensorSpec,
        room: Room,
        rng: np.random.Generator,
        merge_distance_m: float | None = None,
        *,
        profile: NoiseProfile | str = IDEAL,
        decoys: Sequence[Decoy] = (),
        appearance_rng: np.random.Generator | None = None,
        identities: IdentityVectors | None = None,
    ) -> None:
        super().__init__(spec, room)
        self.rng = rng
        self.profile = p = resolve_profile(profile)
        self.merge_distance_m = (
            p.merge_distance_m if merge_distance_m is None else merge_distance_m
        )
        if spec.calibration is not None:
            believed = spec.calibration.world_from_optical()
        else:
            believed = world_from_optical(spec.pose_error.believed(spec.pose))
        # true world -> camera -> world as the sensor believes it to be placed
        self.reported_from_world = believed @ self.camera_from_world
        self._centroid: CentroidError | None = None
        self._height: HeightError | None = None
        self._transients: TransientFalsePositives | None = None
        self._decoys: DecoySightings | None = None
        self._splits: SplitBlobs | None = None
        self._extra_rng = rng
        if appearance_rng is None:
            appearance_rng = _own_generator(rng, 43)
        self.signatures = SignatureModel(self.camera_from_world, appearance_rng)
        self._faces: FaceRecogniser | None = None
        if p.embeddings:
            self._faces = FaceRecogniser(
                identities if identities is not None else IdentityVectors(0),
                self.origin,
                _own_generator(appearance_rng, 1),
                p.embedding_confusion_probability,
            )
        if p == IDEAL:
            return
        # the height generator is spawned last, so the others draw as they did before it
        spawned = rng.spawn(6)
        centroid_rng, transient_rng, decoy_rng, split_rng, self._extra_rng = spawned[:5]
        if p.floor_tilt_deg != (0.0, 0.0) or p.gait_bob_m > 0:
            self._height = HeightError(p, self.origin[:2], spawned[5])
        if p.centroid_error:
            self._centroid = CentroidError(p, spec.noise, centroid_rng)
        if p.false_positives_per_frame > 0:
            self._transients = TransientFalsePositives(self, p, transient_rng)
        if decoys and p.decoy_detection_probability > 0:
            self._decoys = DecoySightings(self, decoys, p, decoy_rng)
        if p.split_duration_s > 0:
            chance = spec.noise.split_probability
            if p.split_probability is not None:
                chance = p.split_probability * FALSE_POSITIVE_TYPE_FACTOR[spec.type.name]
            self._splits = SplitBlobs(chance, p.split_duration_s, split_rng)

    def _miss_probability(self, distance: np.ndarray) -> np.ndarray:
        kind = self.spec.type
        span = max(kind.max_range_m - kind.reliable_range_m, 1e-6)
        beyond = np.clip((distance - kind.reliable_range_m) / span, 0.0, 1.0)
        base = self.spec.miss_probability
        return base + (1.0 - base) * beyond**2

    def observe(self, snap: Snapshot) -> Observation:
        """Simulate one frame of the detector on the world state ``snap``."""
        positions: list[np.ndarray] = []
        heights: list[float] = []
        confidences: list[float] = []
        person_ids: list[int] = []
        source_rows: list[int] = []
        lists = (positions, heights, confidences, person_ids, source_rows)
        extra: list[Blob] = []  # the profile's false detections
        if len(snap):
            self._detect(snap, *lists)
            if positions:
                self._merge(snap, *lists)
                if self._splits is not None:
                    extra += self._splits.blobs(snap.t, person_ids, positions, heights)
                else:
                    self._split(*lists)
        self._clutter(*lists)
        if self._transients is not None:
            extra += self._transients.blobs(snap.t)
        if self._decoys is not None:
            extra += self._decoys.blobs(snap.t)
        return self._finish(snap, *lists, extra=extra)

    def _detect(
        self,
        snap: Snapshot,
        positions: list[np.ndarray],
        heights: list[float],
        confidences: list[float],
        person_ids: list[int],
        rows: list[int],
    ) -> None:
        """Who of ``snap`` the detector finds this frame, where and how confidently."""
        rng = self.rng
        kind = self.spec.type
        noise = self.spec.noise
        scale = self.profile.noise_scale
        n = len(snap)
        mask = self.visibility_mask(snap)
        head_visible, fraction = visible_summary(mask)
        centroid = np.column_stack([snap.pos, 0.55 * snap.height])
        distance = np.linalg.norm(centroid - self.origin, axis=1)
        p_detect = (1.0 - self._miss_probability(distance)) * np.clip(
            (fraction - 0.25) / 0.45, 0.0, 1.0
        )
        p_detect[~head_visible] = 0.0
        detected = np.flatnonzero(rng.random(n) < p_detect)
        if not len(detected):
            return
        ray = snap.pos[detected] - self.origin[:2]
        ray /= np.maximum(np.linalg.norm(ray, axis=1, keepdims=True), 1e-9)
        side = np.column_stack([-ray[:, 1], ray[:, 0]])
        sigma = noise.depth_sigma_at(distance[detected]) * scale
        along = rng.normal(0.0, 1.0, len(detected)) * sigma
        across = rng.normal(0.0, noise.lateral_sigma_m * scale, len(detected))
        xy = snap.pos[detected] + along[:, None] * ray + across[:, None] * side
        if self._centroid is not None:
            xy += self._centroid.sample(snap.t, snap.ids[detected], distance[detected])
        if self.profile.occlusion_shift > 0:
            # the centroid of the points the sensor sees: off-centre when partly hidden
            lateral = visible_lateral_offset(mask[detected]) * snap.radius[detected]
            xy += (self.profile.occlusion_shift * lateral)[:, None] * side
        frac = fraction[detected]
        # with the legs hidden the visible centroid rides higher
        z = snap.height[detected] * (0.55 + 0.15 * (1.0 - frac))
        z = z + rng.normal(0.0, 0.03, len(detected))
        h = snap.height[detected] + rng.normal(0.0, noise.height_sigma_m, len(detected))
        if self._height is not None:
            h += self._height.sample(
                snap.t, snap.ids[detected], snap.pos[detected], snap.vel[detected]
            )
        far = np.maximum(distance[detected] - kind.reliable_range_m, 0.0)
        conf = 0.55 + 0.35 * frac - 0.04 * far + rng.normal(0.0, 0.06, len(detected))
        for j, row in enumerate(detected):
            positions.append(np.array([xy[j, 0], xy[j, 1], z[j]]))
            heights.append(float(h[j]))
            confidences.append(float(np.clip(conf[j], 0.3, 1.0)))
            person_ids.append(int(snap.ids[row]))
            rows.append(int(row))

    @staticmethod
    def _add(
        blobs: Sequence[Blob],
        positions: list[np.ndarray],
        heights: list[float],
        confidences: list[float],
        person_ids: list[int],
        rows: list[int],
    ) -> None:
        """Append false detections (no person behind them)."""
        for xyz, height, confidence in blobs:
            positions.append(xyz)
            heights.append(height)
            confidences.append(confidence)
            person_ids.append(0)
            rows.append(-1)

    def _merge(
        self,
        snap: Snapshot,
        positions: list[np.ndarray],
        heights: list[float],
        confidences: list[float],
        person_ids: list[int],
        rows: list[int],
    ) -> None:
        """People standing closer than the merge distance come out as one blob."""
        if len(rows) < 2:
            return
        true_xy = snap.pos[rows]
        gap = np.linalg.norm(true_xy[:, None] - true_xy[None], axis=2)
        reach = self.merge_distance_m
        keep = list(range(len(rows)))
        merged: set[int] = set()
        for a in range(len(rows)):
            if a in merged:
                continue
            group = [b for b in range(a + 1, len(rows)) if b not in merged and gap[a, b] < reach]
            if not group:
                continue
            members = [a, *group]
            positions[a] = np.mean([positions[m] for m in members], axis=0)
            heights[a] = max(heights[m] for m in members)
            confidences[a] = max(confidences[m] for m in members)
            merged.update(group)
        keep = [i for i in keep if i not in merged]
        for target in (positions, heights, confidences, person_ids, rows):
            target[:] = [target[i] for i in keep]

    def _split(
        self,
        positions: list[np.ndarray],
        heights: list[float],
        confidences: list[float],
        person_ids: list[int],
        rows: list[int],
    ) -> None:
        """Rarely, a person also yields a spurious second blob beside them (one frame)."""
        p = self.profile.split_probability
        if p is None:
            p = self.spec.noise.split_probability
        for i in range(len(rows)):
            if self.rng.random() >= p:
                continue
            angle = self.rng.uniform(0, 2 * math.pi)
            offset = self.rng.uniform(0.35, 0.6) * np.array([math.cos(angle), math.sin(angle), 0])
            positions.append(positions[i] + offset)
            heights.append(heights[i] * self.rng.uniform(0.6, 0.9))
            confidences.append(float(self.rng.uniform(0.2, 0.5)))
            person_ids.append(0)
            rows.append(-1)

    def _clutter(
        self,
        positions: list[np.ndarray],
        heights: list[float],
        confidences: list[float],
        person_ids: list[int],
        rows: list[int],
    ) -> None:
        """Poisson false positives on free floor in view."""
        kind = self.spec.type
        count = self.rng.poisson(self.spec.clutter_per_frame)
        for _ in range(count):
            rng_m = self.rng.uniform(kind.min_range_m + 0.5, kind.reliable_range_m)
            azimuth = self.rng.uniform(-0.45, 0.45) * math.radians(kind.hfov_deg)
            yaw = math.radians(self.spec.pose.yaw_deg) + azimuth
            xy = self.origin[:2] + rng_m * np.array([math.cos(yaw), math.sin(yaw)])
            if not self.room.free(xy, 0.1)[0]:
                continue
            h = float(self.rng.uniform(0.9, 2.0))
            positions.append(np.array([xy[0], xy[1], 0.55 * h]))
            heights.append(h)
            confidences.append(float(np.clip(self.rng.beta(2.0, 4.0), 0.05, 0.6)))
            person_ids.append(0)
            rows.append(-1)

    def _finish(
        self,
        snap: Snapshot,
        positions: list[np.ndarray],
        heights: list[float],
        confidences: list[float],
        person_ids: list[int],
        rows: list[int],
        extra: Sequence[Blob] = (),
    ) -> Observation:
        """The frame's detections through the believed pose, with boxes and appearance.

        ``extra`` (the profile's false detections) come last, with their appearance from
        their own generator, so that they never change the sensor's other draws.
        """
        base = len(rows)
        self._add(extra, positions, heights, confidences, person_ids, rows)
        if not positions:
            return Observation((), ())
        true_world = np.array(positions)
        reported = (
            true_world @ self.reported_from_world[:3, :3].T + self.reported_from_world[:3, 3]
        )
        distance = np.linalg.norm(true_world - self.origin, axis=1)
        row_idx = np.array(rows, dtype=int)
        real = row_idx >= 0
        radius = np.full(len(rows), 0.25)  # clutter: a person-sized box
        radius[real] = snap.radius[row_idx[real]]
        height = np.clip(np.array(heights), 0.0, 10.0)
        boxes = self._boxes(true_world[:, :2], height, radius).tolist()
        if base:
            self._legacy_draws(self.rng, row_idx[:base])
        if len(rows) > base:
            self._legacy_draws(self._extra_rng, row_idx[base:])
        everyone = self._boxes(snap.pos, snap.height, snap.radius) if len(snap) > 1 else None
        looks = self.signatures.measure(snap, row_idx, everyone).tolist()
        faces = self._faces.embed(snap, row_idx) if self._faces is not None else None
        conf = np.clip(np.array(confidences), 0.0, 1.0).tolist()
        rep = reported.tolist()
        dist = distance.tolist()
        hts = height.tolist()
        detections = tuple(
            Detection(
                x=rep[i][0],
                y=rep[i][1],
                z=rep[i][2],
                height=hts[i],
                confidence=conf[i],
                distance=dist[i],
                bbox=tuple(boxes[i]),
                appearance=tuple(looks[i]),
                face=faces[i][0] if faces is not None and faces[i] is not None else None,
                face_confidence=(
                    faces[i][1] if faces is not None and faces[i] is not None else None
                ),
            )
            for i in range(len(rows))
        )
        return Observation(detections, tuple(person_ids))

    def _boxes(self, xy: np.ndarray, height: np.ndarray, radius: np.ndarray) -> np.ndarray:
        """Image boxes ``(u, v, w, h)`` of standing cylinders, clipped to the image."""
        fx, fy, cx, cy = self.spec.type.intrinsics
        ray = xy - self.origin[:2]
        ray /= np.maximum(np.linalg.norm(ray, axis=1, keepdims=True), 1e-9)
        side = np.column_stack([-ray[:, 1], ray[:, 0]]) * radius[:, None]
        n = len(xy)
        corners = np.empty((n, 4, 3))
        corners[:, 0, :2] = corners[:, 2, :2] = xy + side
        corners[:, 1, :2] = corners[:, 3, :2] = xy - side
        corners[:, :2, 2] = 0.0
        corners[:, 2:, 2] = height[:, None]
        cam = corners @ self.camera_from_world[:3, :3].T + self.camera_from_world[:3, 3]
        z = np.maximum(cam[..., 2], 1e-3)
        u = np.clip(fx * cam[..., 0] / z + cx, 0, self.spec.type.width - 1)
        v = np.clip(fy * cam[..., 1] / z + cy, 0, self.spec.type.height - 1)
        u0, u1 = u.min(axis=1).astype(int), u.max(axis=1).astype(int)
        v0, v1 = v.min(axis=1).astype(int), v.max(axis=1).astype(int)
        return np.column_stack([u0, v0, u1 - u0, v1 - v0])

    @staticmethod
    def _legacy_draws(rng: np.random.Generator, rows: np.ndarray) -> None:
        """Draw, and discard, what the hue-only signatures used to draw from ``rng``.

        Signatures now come from the appearance generator; these draws keep every later
        draw of ``rng`` (positions, confidences, misses, clutter) as it always was.
        """
        rng.random((int((rows < 0).sum()), _LEGACY_BINS))
        rng.gamma(20.0, 1 / 20.0, (len(rows), _LEGACY_BINS))
