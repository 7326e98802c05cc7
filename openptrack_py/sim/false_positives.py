"""Confident false detections of a noise profile: transient ones, decoys and split blobs.

Three kinds, each a per-sensor state advanced once a frame (its own random generator,
so the other streams of the simulation do not change when one is switched off):

* :class:`TransientFalsePositives`: something person-like for a fraction of a second (a
  reflection, a door swinging, a chair being moved), drifting slightly, confidence up to
  the profile's maximum;
* :class:`Decoy` and :class:`DecoySightings`: static objects of the room that a people
  detector keeps mistaking for a person at the same place ("a fan got tracked",
  OpenPTrack issue v1 #54): placed once per scenario by :func:`place_decoys`, seen by
  every sensor that can see them;
* :class:`SplitBlobs`: a second, weaker blob beside a detected person (a raised arm, a
  bag) that persists for a fraction of a second (OpenPTrack issue #37).

A blob is ``(xyz, height, confidence)``: a world-frame centroid, the top above the floor
and the detector's confidence. The sensor model maps it through the sensor's believed
pose like any detection.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from openptrack_py.sim.profiles import FALSE_POSITIVE_TYPE_FACTOR, NoiseProfile
from openptrack_py.sim.visibility import SensorView
from openptrack_py.sim.world import Room

Blob = tuple[np.ndarray, float, float]
"""A false detection: world centroid ``(x, y, z)``, height (m), confidence."""

DECOY_KINDS: dict[str, tuple[float, float]] = {
    "coat_rack": (1.6, 1.85),
    "poster_board": (1.4, 1.9),
    "fan": (1.1, 1.4),
}
"""Decoy kinds and the range of their height, metres (within a detector's 1.0-2.3 m)."""


@dataclass(frozen=True)
class Decoy:
    """A static object that people detectors mistake for a person.

    Parameters
    ----------
    kind : str
        One of :data:`DECOY_KINDS`.
    x, y : float
        Where it stands, metres.
    height_m : float
        Its top above the floor, metres.
    sway_m : float
        Amplitude of its oscillation (a fan turning), metres; 0 for a still object.
    sway_period_s : float
        Period of the oscillation, seconds.
    sway_heading_rad : float
        Direction of the oscillation on the floor, radians.
    """

    kind: str
    x: float
    y: float
    height_m: float
    sway_m: float = 0.0
    sway_period_s: float = 8.0
    sway_heading_rad: float = 0.0

    def position_at(self, t: float) -> np.ndarray:
        """Its detected centroid ``(x, y, z)`` at scenario time ``t``."""
        s = self.sway_m * math.sin(2 * math.pi * t / self.sway_period_s)
        return np.array(
            [
                self.x + s * math.cos(self.sway_heading_rad),
                self.y + s * math.sin(self.sway_heading_rad),
                0.55 * self.height_m,
            ]
        )


def place_decoys(
    room: Room, views: Sequence[SensorView], count: int, rng: np.random.Generator
) -> tuple[Decoy, ...]:
    """``count`` decoys on free floor that some sensor sees within its reliable range.

    Decoys stand preferably within 1.5 m of a wall (where furniture stands), at least
    1 m apart; a fan oscillates by 0.1-0.2 m. Fewer than ``count`` when the room has no
    more such places.

    Parameters
    ----------
    room : Room
        The room (free floor).
    views : sequence of SensorView
        The scenario's sensors.
    count : int
        How many decoys to place.
    rng : numpy.random.Generator
        The scenario's generator for decoys.
    """
    decoys: list[Decoy] = []
    kinds = list(DECOY_KINDS)
    for attempt in range(4000):
        if len(decoys) >= count or not views:
            break
        xy = room.random_free_point(rng, 0.3)
        near_wall = min(xy[0], xy[1], room.width - xy[0], room.depth - xy[1]) <= 1.5
        if attempt < 2000 and not near_wall:
            continue
        if any(math.hypot(xy[0] - d.x, xy[1] - d.y) < 1.0 for d in decoys):
            continue
        if not any(_in_reliable_view(view, xy) for view in views):
            continue
        kind = kinds[int(rng.integers(len(kinds)))]
        height = float(rng.uniform(*DECOY_KINDS[kind]))
        sway = float(rng.uniform(0.1, 0.2)) if kind == "fan" else 0.0
        decoys.append(
            Decoy(
                kind, float(xy[0]), float(xy[1]), height, sway,
                float(rng.uniform(6.0, 12.0)), float(rng.uniform(0.0, math.pi)),
            )
        )  # fmt: skip
    return tuple(decoys)


def _in_reliable_view(view: SensorView, xy: np.ndarray) -> bool:
    kind = view.spec.type
    dist = math.hypot(xy[0] - view.origin[0], xy[1] - view.origin[1])
    if not kind.min_range_m + 0.5 <= dist <= kind.reliable_range_m:
        return False
    points = np.array([[xy[0], xy[1], 1.0], [xy[0], xy[1], 0.6]])
    return bool(view.sees(points).all())


class DecoySightings:
    """One sensor's detections of the scenario's decoys.

    Parameters
    ----------
    view : SensorView
        The sensor (which decoys it can see: in view, not behind furniture).
    decoys : sequence of Decoy
        The scenario's decoys.
    profile : NoiseProfile
        Detection probability (times the sensor type's false-positive factor,
        :data:`~openptrack_py.sim.profiles.FALSE_POSITIVE_TYPE_FACTOR`) and confidence
        range.
    rng : numpy.random.Generator
        This sensor's generator for decoys alone.
    """

    def __init__(
        self,
        view: SensorView,
        decoys: Sequence[Decoy],
        profile: NoiseProfile,
        rng: np.random.Generator,
    ) -> None:
        self.profile = profile
        self.rng = rng
        self.noise = view.spec.noise
        factor = FALSE_POSITIVE_TYPE_FACTOR[view.spec.type.name]
        self.probability = min(1.0, profile.decoy_detection_probability * factor)
        self.origin = view.origin
        self.decoys = tuple(d for d in decoys if view.sees(d.position_at(0.0)[None])[0])

    def blobs(self, t: float) -> list[Blob]:
        """The decoy detections at scenario time ``t``."""
        out: list[Blob] = []
        if not self.decoys:
            return out
        p = self.profile
        rng = self.rng
        n = len(self.decoys)
        seen = rng.random(n) < self.probability
        conf = rng.uniform(*p.decoy_confidence, n)
        jitter = rng.normal(0.0, 1.0, (n, 2))
        for i, decoy in enumerate(self.decoys):
            if not seen[i]:
                continue
            xyz = decoy.position_at(t)
            dist = float(np.linalg.norm(xyz - self.origin))
            sigma = float(self.noise.depth_sigma_at(dist)) * p.noise_scale
            xyz[:2] += sigma * jitter[i]
            out.append((xyz, decoy.height_m, float(conf[i])))
        return out


class TransientFalsePositives:
    """One sensor's transient confident false positives.

    New ones appear as a Poisson process on free floor in the sensor's view within its
    reliable range, live an exponential time (mean ``false_positive_duration_s``), drift
    slowly, and are reported every frame they live; the mean number present per frame is
    ``false_positives_per_frame`` times the sensor type's factor
    (:data:`~openptrack_py.sim.profiles.FALSE_POSITIVE_TYPE_FACTOR`).

    Parameters
    ----------
    view : SensorView
        The sensor.
    profile : NoiseProfile
        Rate, lifetime, drift and confidence.
    rng : numpy.random.Generator
        This sensor's generator for these false positives alone.
    """

    def __init__(self, view: SensorView, profile: NoiseProfile, rng: np.random.Generator):
        self.view = view
        self.profile = profile
        self.rng = rng
        kind = view.spec.type
        present = profile.false_positives_per_frame * FALSE_POSITIVE_TYPE_FACTOR[kind.name]
        # a false positive is reported on ceil(lifetime * rate) frames: on average half a
        # frame more than its mean lifetime
        frames = profile.false_positive_duration_s * view.spec.rate_hz + 0.5
        self.births_per_frame = present / frames
        # (birth time, death time, xy, velocity, height, confidence)
        self._alive: list[tuple[float, float, np.ndarray, np.ndarray, float, float]] = []

    def blobs(self, t: float) -> list[Blob]:
        """The transient false positives at scenario time ``t``."""
        rng = self.rng
        p = self.profile
        self._alive = [fp for fp in self._alive if fp[1] > t]
        for _ in range(int(rng.poisson(self.births_per_frame))):
            born = self._spawn(t)
            if born is not None:
                self._alive.append(born)
        out: list[Blob] = []
        top = p.false_positive_max_confidence
        for birth, _, xy, vel, height, conf in self._alive:
            at = xy + vel * (t - birth)
            c = float(np.clip(conf + rng.normal(0.0, 0.03), 0.0, top))
            out.append((np.array([at[0], at[1], 0.55 * height]), height, c))
        return out

    def _spawn(self, t: float) -> tuple[float, float, np.ndarray, np.ndarray, float, float] | None:
        rng = self.rng
        p = self.profile
        view = self.view
        kind = view.spec.type
        distance = rng.uniform(kind.min_range_m + 0.5, kind.reliable_range_m)
        azimuth = rng.uniform(-0.45, 0.45) * math.radians(kind.hfov_deg)
        heading = math.radians(view.spec.pose.yaw_deg) + azimuth
        xy = view.origin[:2] + distance * np.array([math.cos(heading), math.sin(heading)])
        life = rng.exponential(p.false_positive_duration_s)
        speed = rng.uniform(0.0, p.false_positive_drift_m_s)
        course = rng.uniform(0.0, 2 * math.pi)
        height = float(rng.uniform(1.0, 1.9))
        top = p.false_positive_max_confidence
        conf = float(rng.uniform(min(0.25, top), top))
        if not view.room.free(xy, 0.1)[0]:
            return None
        vel = speed * np.array([math.cos(course), math.sin(course)])
        return (t, t + life, xy, vel, height, conf)


class SplitBlobs:
    """One sensor's persistent split blobs: a weaker second blob beside a person.

    Parameters
    ----------
    probability : float
        Per detected person and frame, probability that a split starts.
    duration_s : float
        Mean lifetime of a split (exponential), seconds.
    rng : numpy.random.Generator
        This sensor's generator for splits alone.
    """

    def __init__(self, probability: float, duration_s: float, rng: np.random.Generator):
        self.probability = probability
        self.duration_s = duration_s
        self.rng = rng
        # person id -> (death time, offset (x, y, 0), height factor, confidence)
        self._active: dict[int, tuple[float, np.ndarray, float, float]] = {}

    def blobs(
        self,
        t: float,
        ids: Sequence[int],
        positions: Sequence[np.ndarray],
        heights: Sequence[float],
    ) -> list[Blob]:
        """Split blobs beside this frame's detections (person ``ids`` at ``positions``)."""
        rng = self.rng
        out: list[Blob] = []
        starts = rng.random(len(ids)) < self.probability
        for j, pid in enumerate(ids):
            split = self._active.get(pid)
            if split is not None and split[0] <= t:
                split = None
                del self._active[pid]
            if split is None and starts[j]:
                angle = rng.uniform(0, 2 * math.pi)
                offset = rng.uniform(0.3, 0.55) * np.array([math.cos(angle), math.sin(angle), 0])
                split = (
                    t + rng.exponential(self.duration_s),
                    offset,
                    float(rng.uniform(0.6, 0.9)),
                    float(rng.uniform(0.3, 0.6)),
                )
                self._active[pid] = split
            if split is None:
                continue
            wobble = np.append(rng.normal(0.0, 0.03, 2), 0.0)
            out.append((positions[j] + split[1] + wobble, heights[j] * split[2], split[3]))
        return out
