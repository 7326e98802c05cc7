"""The floor and the people for any mounting: forward, tilted and straight down.

Rendered scenes (the simulator's RGB-D renderer, real sensor intrinsics and depth noise)
seen by sensors with no pose and no hand-given plane: the detector must find the floor
and everyone on it. Ceiling-mounted sensors looking straight down are the common
people-counting layout; near a wall or in a corridor they also see walls that an upright
camera's floor could be.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from openptrack_py.config import DetectorConfig, GroundConfig, Pose, SensorConfig
from openptrack_py.detection.ground import GroundPlane, GroundTracker
from openptrack_py.detection.pipeline import PeopleDetector
from openptrack_py.geometry import apply, invert, world_from_optical
from openptrack_py.sim.render import DepthRenderer
from openptrack_py.sim.sensors import SensorSpec
from openptrack_py.sim.world import Room
from tests.conftest import people_snapshot, python_env

ROOM = Room(8.0, 6.0)
CORRIDOR = Room(12.0, 2.2)
PEOPLE = [(3.0, 2.6, 1.75, 0.22, 20, 200), (4.2, 3.6, 1.62, 0.2, 120, 40)]

# (name, room, pose): forward, tilted 15-60 degrees, straight down (centre, near a wall,
# in a corridor, turned), each with a little roll where a real mount would have some.
MOUNTINGS = [
    ("forward", ROOM, Pose(x=0.2, y=3.0, z=1.4, yaw_deg=0.0, pitch_deg=0.0, roll_deg=2.0)),
    ("tilt15", ROOM, Pose(x=0.2, y=3.0, z=2.2, yaw_deg=5.0, pitch_deg=15.0)),
    ("tilt30", ROOM, Pose(x=0.2, y=2.0, z=2.6, yaw_deg=20.0, pitch_deg=30.0, roll_deg=-4.0)),
    ("tilt45", ROOM, Pose(x=1.0, y=3.0, z=2.8, yaw_deg=0.0, pitch_deg=45.0, roll_deg=3.0)),
    ("tilt60", ROOM, Pose(x=1.5, y=3.0, z=2.9, yaw_deg=0.0, pitch_deg=60.0)),
    ("down", ROOM, Pose(x=3.6, y=3.1, z=2.9, yaw_deg=0.0, pitch_deg=90.0)),
    ("down_turned", ROOM, Pose(x=3.6, y=3.1, z=2.9, yaw_deg=67.0, pitch_deg=88.0, roll_deg=1.5)),
    ("down_near_wall", ROOM, Pose(x=3.6, y=5.3, z=2.85, yaw_deg=90.0, pitch_deg=90.0)),
    ("down_corridor", CORRIDOR, Pose(x=6.0, y=1.1, z=2.8, yaw_deg=90.0, pitch_deg=90.0)),
]


def _render(pose: Pose, room: Room, people: list, *, kind: str = "kinect2", seed: int = 0):
    spec = SensorSpec.from_config(SensorConfig(id="cam", type=kind, pose=pose))  # type: ignore[arg-type]
    return DepthRenderer(spec, room, np.random.default_rng(seed)).render(people_snapshot(people))


def _cloud(frame) -> np.ndarray:
    k = frame.intrinsics
    v, u = np.nonzero(np.isfinite(frame.depth) & (frame.depth > 0))
    z = frame.depth[v, u].astype(np.float64)
    return np.column_stack([(u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z])


def _visible(pose: Pose, room: Room, people: list) -> list:
    """The people whose head the sensor sees (the test is about the floor, not the view)."""
    shot = _render(pose, room, people)
    return [p for p, seen in zip(people, shot.head_visible > 20, strict=True) if seen]


@pytest.mark.parametrize(("name", "room", "pose"), MOUNTINGS, ids=[m[0] for m in MOUNTINGS])
@pytest.mark.parametrize("kind", ["kinect2", "sr4500"])
def test_the_floor_is_found_for_any_mounting(name: str, room: Room, pose: Pose, kind: str) -> None:
    truth = GroundPlane.from_world_pose(world_from_optical(pose))
    tracker = GroundTracker(GroundConfig(mode="auto"), rng=np.random.default_rng(3))
    shot = _render(pose, room, PEOPLE, kind=kind)
    plane = tracker.update(_cloud(shot.frame).astype(np.float32))
    assert plane is not None, name
    assert plane.angle_to(truth) < 1.5, (name, plane, truth)
    assert plane.offset == pytest.approx(truth.offset, abs=0.04), (name, plane, truth)


@pytest.mark.parametrize("name", ["down", "down_turned", "down_near_wall", "tilt60"])
def test_people_below_a_ceiling_sensor_are_found_where_they_stand(name: str) -> None:
    """No floor given, no pose: every visible person within 0.1 m, at the head's height.

    Seen from above the top of the head is the person's centre: the position is not
    pushed away from the sensor as it is for a sensor that sees people from the side.
    """
    _, room, pose = next(m for m in MOUNTINGS if m[0] == name)
    people = [(3.3, 3.0, 1.75, 0.22, 20, 200), (4.3, 3.5, 1.62, 0.2, 120, 40)]
    if name == "down_near_wall":
        people = [(3.2, 5.0, 1.75, 0.22, 20, 200), (4.1, 4.6, 1.62, 0.2, 120, 40)]
    if name == "tilt60":
        people = [(3.0, 2.6, 1.75, 0.22, 20, 200), (3.4, 3.6, 1.62, 0.2, 120, 40)]
    seen = _visible(pose, room, people)
    assert seen, "the scene must show someone"
    detector = PeopleDetector(
        DetectorConfig(ground=GroundConfig(mode="auto")),
        sensor_type="kinect2",
        frame_id="overhead",
        rng=np.random.default_rng(1),
    )
    found = None
    for seed in range(3):  # the floor is found on the first frame; later ones refine it
        found = detector.detect(_render(pose, room, people, seed=seed).frame)
    assert found is not None and found.ground is not None
    world = np.column_stack([np.array(seen)[:, :2], np.zeros(len(seen))])
    optical = apply(invert(world_from_optical(pose)), world)
    truth = apply(found.ground.ground_from_camera(), optical)[:, :2]
    xy = np.array([d.position[:2] for d in found.detections]).reshape(-1, 2)
    assert len(xy) == len(truth), (xy, truth)
    dist = np.linalg.norm(xy[:, None] - truth[None], axis=2)
    assert dist.min(axis=1).max() < 0.1, dist
    for d in found.detections:
        nearest = int(np.argmin(np.linalg.norm(truth - d.position[:2], axis=1)))
        assert d.height == pytest.approx(seen[nearest][2], abs=0.08)


def test_a_steep_view_pushes_less_than_a_side_view() -> None:
    """The push towards the body's centre follows the ray's angle from the vertical."""
    from openptrack_py.detection.pipeline import surface_push

    side = surface_push(0.12, reach=np.array([4.0]), drop=np.array([0.8]))
    below = surface_push(0.12, reach=np.array([0.0]), drop=np.array([1.2]))
    assert side[0] == pytest.approx(0.12 * math.sin(math.atan2(4.0, 0.8)))
    assert below[0] == 0.0


def test_detect_finds_floor_and_people_in_a_folder_of_overhead_frames(tmp_path: Path) -> None:
    """``openptrack detect`` on a recorded overhead sensor: no pose, no plane given."""
    folder = tmp_path / "top_b"
    env = python_env()
    record = [sys.executable, "-m", "openptrack_py.cli", "record-sensor"]
    subprocess.run(
        [*record, "sim:overhead:top_b", str(folder), "--frames", "150"],
        check=True, env=env, capture_output=True, timeout=300,
    )  # fmt: skip
    out = subprocess.run(
        [sys.executable, "-m", "openptrack_py.cli", "detect", str(folder), "--format", "json"],
        check=True, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    records = [json.loads(line) for line in out.stdout.splitlines()]
    assert len(records) == 150
    assert all(r["status"] != "no-ground" for r in records)
    _, _, c, d = records[-1]["ground"]
    assert c == pytest.approx(-1.0, abs=0.001) and d == pytest.approx(2.9, abs=0.03)
    heights = [det["height"] for r in records for det in r["detections"]]
    assert len(heights) >= 60, len(heights)
    assert all(0.8 <= h <= 2.1 for h in heights), heights
