"""Simulated calibration walks: one person walking through a network's room.

:func:`simulate_walk` plays a scenario's room and sensors (``crowd``, ``installation``,
or a network file's sensors) with one person walking between random points of the
floor, preferably points that two or more sensors see (as a person calibrating a network
is told to), round the furniture, through the detection-level sensor models under a noise profile
(``realistic`` by default: misses, centroid error, outliers, false positives, decoys,
per-sensor clock offsets). Each sensor's detections come out as an *uncalibrated* sensor
reports them: in its own floor frame (converted from the simulated world positions with
the sensor's pose), stamped on its own clock (true time plus its clock offset). The
session keeps the truth for scoring: each sensor's floor pose and clock offset, the
walker's true path and which detections are the walker's.

:func:`perturb_poses` moves poses by a random 10-20 cm and 2-4 degrees each, the
calibration errors a refinement is meant to remove.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from openptrack_py.calibration.walk import Pose2D, WalkTrack
from openptrack_py.calibration.walk_tracks import floor_from_world
from openptrack_py.config import Pose, SensorConfig
from openptrack_py.geometry import world_from_optical
from openptrack_py.sim.profiles import NoiseProfile
from openptrack_py.sim.scenarios import build_scenario
from openptrack_py.sim.sensor_spec import SensorSpec
from openptrack_py.sim.simulator import DEFAULT_START_TIME, SensorFrame, Simulator, TruthFrame
from openptrack_py.sim.visibility import SensorView
from openptrack_py.sim.walker import CalibrationWalker, walk_goals
from openptrack_py.sim.world import Director

__all__ = [
    "WalkSession",
    "floor_from_reported",
    "perturb_poses",
    "simulate_walk",
]


@dataclass(frozen=True, eq=False)
class WalkSession:
    """A simulated calibration walk and its truth.

    Parameters
    ----------
    tracks : tuple of WalkTrack
        Each sensor's detections in its own floor frame, stamped on its own clock.
    true_poses : Mapping of str to Pose2D
        Each sensor's true floor pose in the world.
    clock_offsets_s : Mapping of str to float
        Each sensor's true clock offset (its stamps minus the true time), seconds.
    believed_poses : Mapping of str to Pose2D
        The floor poses the profile's calibration error gives the sensors (what a
        checkerboard calibration of this network would have left).
    walker : ndarray
        ``(m, 3)`` true path: UNIX time, x, y.
    is_walker : Mapping of str to ndarray
        Per sensor, which of its track's detections are the walker's (the rest are
        false positives).
    scenario : str
        The scenario whose room and sensors were used.
    seed : int
        The seed.
    profile : str
        The noise profile.
    duration_s : float
        Length of the walk.
    """

    tracks: tuple[WalkTrack, ...]
    true_poses: Mapping[str, Pose2D]
    clock_offsets_s: Mapping[str, float]
    believed_poses: Mapping[str, Pose2D]
    walker: np.ndarray
    is_walker: Mapping[str, np.ndarray]
    scenario: str
    seed: int
    profile: str
    duration_s: float

    def relative_offsets(self, reference: str) -> dict[str, float]:
        """True clock offsets relative to ``reference``'s clock."""
        base = self.clock_offsets_s[reference]
        return {k: v - base for k, v in self.clock_offsets_s.items()}


def floor_from_reported(believed: Pose) -> np.ndarray:
    """4x4 transform from world positions reported through ``believed`` to the floor frame.

    A simulated sensor maps what it sees to the world with the pose it believes
    (:func:`~openptrack_py.calibration.walk_tracks.floor_from_world` undoes it).
    """
    return floor_from_world(world_from_optical(believed))


def _believed(spec: SensorSpec) -> Pose:
    err = spec.pose_error
    return spec.pose.model_copy(
        update={
            "x": spec.pose.x + err.dx,
            "y": spec.pose.y + err.dy,
            "yaw_deg": spec.pose.yaw_deg + err.dyaw_deg,
        }
    )


def simulate_walk(
    scenario: str = "crowd",
    *,
    seed: int = 0,
    duration_s: float = 60.0,
    profile: str | NoiseProfile = "realistic",
    sensors: Sequence[SensorConfig] | None = None,
    overlap_preference: float = 1.0,
    pause_s: tuple[float, float] = (0.0, 1.5),
    start_time: float = DEFAULT_START_TIME,
) -> WalkSession:
    """One person walking for ``duration_s`` through a scenario's room.

    Parameters
    ----------
    scenario : str
        Scenario whose room and sensors to use (``crowd``: 3 Kinect v2 in a 10 x 10 m
        room; ``installation``: 3 in an 8 x 6 m art space; ...); its people are
        replaced by the walker.
    seed : int
        Seed of the walk and of the sensors' noise (their clock offsets, calibration
        errors, misses, false positives).
    duration_s : float
        Length of the walk, seconds.
    profile : {"realistic", "ideal", "harsh"} or NoiseProfile
        Noise profile of the sensors.
    sensors : sequence of SensorConfig, optional
        Replace the scenario's sensors (e.g. a network file's).
    overlap_preference : float
        Share of the walker's goals drawn among points seen by two sensors or more.
    pause_s : tuple of float
        Range of the pause at each goal, seconds.
    start_time : float
        UNIX time of the walk's start (true clock).

    Returns
    -------
    WalkSession
        The tracks and the truth.
    """
    base = build_scenario(
        scenario, seed=seed, duration_s=duration_s, sensors=sensors, profile=profile
    )
    views = [SensorView(spec, base.room) for spec in base.sensors]
    sample = walk_goals(base.room, views, overlap_preference)

    def director(rng: np.random.Generator) -> Director:
        return CalibrationWalker(sample, pause_s, rng)

    walk = dataclasses.replace(
        base, make_director=director, description="one person walking to calibrate"
    )
    sim = Simulator(walk, start_time=start_time, ground_truth_rate_hz=30.0)
    rows, path = _record(sim, walk.sensors)
    tracks, labels = _walk_tracks(rows)
    specs = {s.id: s for s in walk.sensors}
    return WalkSession(
        tracks=tuple(tracks),
        true_poses={k: Pose2D.from_pose(s.pose) for k, s in specs.items()},
        clock_offsets_s={k: s.clock_offset_s for k, s in specs.items()},
        believed_poses={k: Pose2D.from_pose(_believed(s)) for k, s in specs.items()},
        walker=np.array(path, dtype=float).reshape(-1, 3),
        is_walker=labels,
        scenario=scenario,
        seed=seed,
        profile=walk.profile.name,
        duration_s=float(duration_s),
    )


_Row = tuple[float, float, float, float, bool]
"""One detection in its sensor's floor frame: stamp, x, y, confidence, is the walker."""


def _record(
    sim: Simulator, sensors: Sequence[SensorSpec]
) -> tuple[dict[str, list[_Row]], list[tuple[float, float, float]]]:
    """Play the walk: each sensor's detections in its floor frame, the walker's true path."""
    to_floor = {s.id: floor_from_reported(_believed(s)) for s in sensors}
    rows: dict[str, list[_Row]] = {s.id: [] for s in sensors}
    path: list[tuple[float, float, float]] = []
    for event in sim.events():
        if isinstance(event, TruthFrame):
            path += [(event.time, p.x, p.y) for p in event.frame.people]
            continue
        if not isinstance(event, SensorFrame):  # pragma: no cover - the two event kinds
            continue
        batch = event.batch
        if not batch.detections:
            continue
        reported = np.array([(d.x, d.y, d.z) for d in batch.detections])
        tf = to_floor[batch.sensor_id]
        floor = reported @ tf[:3, :3].T + tf[:3, 3]
        rows[batch.sensor_id] += [
            (batch.stamp, float(f[0]), float(f[1]), d.confidence, pid != 0)
            for f, d, pid in zip(floor, batch.detections, event.person_ids, strict=True)
        ]
    return rows, path


def _walk_tracks(
    rows: Mapping[str, Sequence[_Row]],
) -> tuple[list[WalkTrack], dict[str, np.ndarray]]:
    """One track per sensor, in time order, and which of its detections are the walker's."""
    tracks, labels = [], {}
    for sid, values in rows.items():
        arr = np.array([v[:4] for v in values], dtype=float).reshape(-1, 4)
        mine = np.array([v[4] for v in values], dtype=bool)
        order = np.argsort(arr[:, 0], kind="stable")
        tracks.append(WalkTrack(sid, arr[order, 0], arr[order, 1:3], arr[order, 3]))
        labels[sid] = mine[order]
    return tracks, labels


def perturb_poses(
    poses: Mapping[str, Pose2D],
    seed: int | np.random.Generator = 0,
    offset_m: tuple[float, float] = (0.10, 0.20),
    yaw_deg: tuple[float, float] = (2.0, 4.0),
) -> dict[str, Pose2D]:
    """Each pose moved by a random distance in ``offset_m`` and turned by ``yaw_deg``.

    The direction of the move and the sign of the turn (about the sensor's own position)
    are drawn per sensor, in the order of ``poses``.

    Parameters
    ----------
    poses : Mapping of str to Pose2D
        The poses to perturb.
    seed : int or numpy.random.Generator
        Randomness.
    offset_m : tuple of float
        Range of the position error, metres.
    yaw_deg : tuple of float
        Range of the heading error, degrees.
    """
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    out = {}
    for sid, pose in poses.items():
        dist = float(rng.uniform(*offset_m))
        heading = float(rng.uniform(0.0, 2 * math.pi))
        turn = float(rng.uniform(*yaw_deg)) * (1.0 if rng.random() < 0.5 else -1.0)
        out[sid] = Pose2D(
            pose.x + dist * math.cos(heading),
            pose.y + dist * math.sin(heading),
            pose.yaw_deg + turn,
        )
    return out
