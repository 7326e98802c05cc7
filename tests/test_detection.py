"""Tests for openptrack_py.detection: floor, people blobs, robustness, appearance, HOG.

The detector runs on frames rendered by :mod:`openptrack_py.sim.render` (with each sensor
type's noise) or on synthetic clouds whose truth is known exactly. Every run is seeded;
rates are measured over many varied frames and asserted with their floor.
"""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest

from openptrack_py.config import (
    BackgroundConfig,
    DetectorConfig,
    GroundConfig,
    HogConfig,
    Pose,
    SensorConfig,
)
from openptrack_py.detection.appearance import (
    ACHROMATIC_BINS,
    bhattacharyya,
    colour_signatures,
    hue_correlation,
    hue_histograms,
    rgb_to_hsv,
    signature_bins,
)
from openptrack_py.detection.background import BackgroundModel
from openptrack_py.detection.frame import Frame, Intrinsics, image_box
from openptrack_py.detection.ground import (
    GroundPlane,
    GroundTracker,
    choose_ground,
    estimate_ground,
)
from openptrack_py.detection.pipeline import DetectionResult, PeopleDetector
from openptrack_py.errors import ConfigError
from openptrack_py.eval.detector import evaluate_detector
from openptrack_py.geometry import apply, invert, world_from_optical
from openptrack_py.sim.render import DepthRenderer, RenderedFrame
from openptrack_py.sim.sensors import SensorSpec
from openptrack_py.sim.world import Obstacle, Room
from tests.conftest import ROOT, people_snapshot, python_env

# --------------------------------------------------------------------------- helpers


_snap = people_snapshot


EMPTY = _snap([])


def _spec(pose: Pose, kind: str = "kinect2") -> SensorSpec:
    return SensorSpec.from_config(SensorConfig(id="cam", type=kind, pose=pose))  # type: ignore[arg-type]


def _renderer(pose: Pose, room: Room, *, seed: int = 0, kind: str = "kinect2") -> DepthRenderer:
    return DepthRenderer(_spec(pose, kind), room, np.random.default_rng(seed))


def _detector(
    pose: Pose | None,
    config: DetectorConfig | None = None,
    *,
    kind: str = "kinect2",
    seed: int = 0,
    frame_id: str = "cam",
) -> PeopleDetector:
    return PeopleDetector(
        config or DetectorConfig(),
        world_from_camera=None if pose is None else world_from_optical(pose),
        sensor_type=kind,
        frame_id=frame_id,
        rng=np.random.default_rng(seed),
    )


def _xy(result: DetectionResult) -> np.ndarray:
    return np.array([d.position[:2] for d in result.detections]).reshape(-1, 2)


def _matches(found: np.ndarray, truth: np.ndarray, radius: float) -> bool:
    """Whether detections and people pair up one to one, each pair within ``radius``."""
    if len(found) != len(truth):
        return False
    dist = np.linalg.norm(found[:, None, :] - truth[None, :, :], axis=2)
    from scipy.optimize import linear_sum_assignment

    rows, cols = linear_sum_assignment(dist)
    return bool((dist[rows, cols] <= radius).all())


def _optical_points(frame: Frame) -> np.ndarray:
    """The valid pixels of a depth frame as optical-frame points."""
    k = frame.intrinsics
    assert k is not None and frame.depth is not None
    v, u = np.nonzero(np.isfinite(frame.depth) & (frame.depth > 0))
    z = frame.depth[v, u].astype(np.float64)
    return np.column_stack([(u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z])


def _to_floor_frame(result: DetectionResult, pose: Pose, xy: np.ndarray) -> np.ndarray:
    """World floor positions in a pose-less detector's floor-aligned frame."""
    assert result.ground is not None
    world = np.column_stack([xy, np.zeros(len(xy))])
    optical = apply(invert(world_from_optical(pose)), world)
    return apply(result.ground.ground_from_camera(), optical)[:, :2]


# --------------------------------------------------------------------------- ground

TILTED = Pose(x=0.0, y=0.0, z=2.6, yaw_deg=0.0, pitch_deg=35.0, roll_deg=10.0)


def _room_cloud(pose: Pose, seed: int = 0) -> tuple[np.ndarray, int, int]:
    """Optical-frame cloud of a floor, a wall, a big table top at 0.75 m and a box.

    Returns the points and how many lie on the floor and on the table top.
    """
    rng = np.random.default_rng(seed)

    def patch(n: int, lo: Sequence[float], hi: Sequence[float]) -> np.ndarray:
        return rng.uniform(lo, hi, size=(n, 3))

    floor = patch(3000, (1.0, -3.0, 0.0), (6.5, 3.0, 0.0))
    table = patch(4000, (2.0, -1.5, 0.75), (4.0, 1.5, 0.75))  # more points than the floor
    wall = patch(2500, (7.0, -3.0, 0.0), (7.0, 3.0, 3.0))
    box = np.vstack(
        [
            patch(300, (4.5, 1.5, 0.5), (5.0, 2.0, 0.5)),
            patch(300, (4.5, 1.5, 0.0), (4.5, 2.0, 0.5)),
            patch(300, (4.5, 1.5, 0.0), (5.0, 1.5, 0.5)),
        ]
    )
    world = np.vstack([floor, table, wall, box])
    world += rng.normal(0.0, 0.01, world.shape)
    optical = apply(invert(world_from_optical(pose)), world)
    return optical[optical[:, 2] > 0.3], len(floor), len(table)


def _truth(pose: Pose) -> GroundPlane:
    return GroundPlane.from_world_pose(world_from_optical(pose))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_estimate_ground_finds_the_lowest_plane_not_the_largest(seed: int) -> None:
    points, n_floor, n_table = _room_cloud(TILTED, seed)
    assert n_table > n_floor  # a largest-plane rule would pick the table
    plane = estimate_ground(points, np.random.default_rng(seed))
    assert plane is not None
    truth = _truth(TILTED)
    assert plane.angle_to(truth) < 1.0
    assert plane.offset == pytest.approx(2.6, abs=0.02)
    assert plane.source == "auto"
    assert plane.tilt_deg() == pytest.approx(35.0, abs=1.0)


def test_estimate_ground_rejects_planes_outside_the_allowance() -> None:
    points, _, _ = _room_cloud(TILTED)
    truth = np.asarray(_truth(TILTED).normal)
    # the true up turned by 40 degrees about the optical x axis
    c, s = math.cos(math.radians(40)), math.sin(math.radians(40))
    turned = np.array([[1, 0, 0], [0, c, -s], [0, s, c]]) @ truth
    rng = np.random.default_rng(0)
    assert estimate_ground(points, rng, expected_up=turned, angle_allowance_deg=20.0) is None
    found = estimate_ground(points, rng, expected_up=turned, angle_allowance_deg=45.0)
    assert found is not None and found.angle_to(_truth(TILTED)) < 1.0


def test_ground_tracker_uses_the_expected_tilt() -> None:
    """A camera pitched down 35 degrees: the expected up leans towards the optical axis."""
    points, _, _ = _room_cloud(TILTED)
    cfg = GroundConfig(mode="auto", expected_tilt_deg=35.0, angle_allowance_deg=20.0)
    plane = GroundTracker(cfg, rng=np.random.default_rng(0)).update(points.astype(np.float32))
    assert plane is not None and plane.angle_to(_truth(TILTED)) < 1.0


def test_ground_tracker_refines_unless_locked_and_calibration_overrules_a_wrong_estimate() -> None:
    """Refinement follows a floor that drifts 2 cm (within the inlier band); a locked one stays."""
    points, _, _ = _room_cloud(TILTED)
    truth = _truth(TILTED)
    lowered = points - 0.02 * np.asarray(truth.normal)  # the whole scene 2 cm further down
    free = GroundTracker(GroundConfig(mode="auto"), rng=np.random.default_rng(0))
    locked = GroundTracker(GroundConfig(mode="auto", lock=True), rng=np.random.default_rng(0))
    first = free.update(points)
    assert first == locked.update(points)
    for _ in range(40):
        refined = free.update(lowered)
        kept = locked.update(lowered)
    assert kept == first
    assert refined.offset == pytest.approx(first.offset + 0.02, abs=0.003)
    # "both" (Munaro et al., OpenPTrack, §5.1): a calibration far from the estimate is
    # kept, a close one yields
    far = GroundPlane(truth.normal, truth.offset + 0.2, "calibration")
    both = GroundTracker(GroundConfig(mode="both"), far, rng=np.random.default_rng(0))
    assert both.update(points) == far
    near = GroundPlane(truth.normal, truth.offset + 0.05, "calibration")
    both = GroundTracker(GroundConfig(mode="both"), near, rng=np.random.default_rng(0))
    chosen = both.update(points)
    assert chosen.source == "auto" and chosen.offset == pytest.approx(truth.offset, abs=0.02)


def test_ground_tracker_without_pose_finds_a_steep_floor() -> None:
    steep = Pose(x=0.0, y=0.0, z=2.6, pitch_deg=50.0, roll_deg=15.0)
    points, _, _ = _room_cloud(steep)
    plane = GroundTracker(GroundConfig(mode="auto"), rng=np.random.default_rng(0)).update(points)
    assert plane is not None
    assert plane.angle_to(_truth(steep)) < 1.0
    assert plane.offset == pytest.approx(2.6, abs=0.02)


def _perturbed(**change: float) -> GroundPlane:
    return GroundPlane.from_world_pose(world_from_optical(TILTED.model_copy(update=change)))


def test_choose_ground_keeps_an_estimate_close_to_calibration() -> None:
    calibrated = _truth(TILTED)
    for close in (_perturbed(pitch_deg=39.0), _perturbed(z=2.72), _perturbed(roll_deg=6.0)):
        assert choose_ground(close, calibrated) is close
    for far in (_perturbed(pitch_deg=42.0), _perturbed(z=2.8), _perturbed(z=2.4)):
        assert choose_ground(far, calibrated) is calibrated
    # the allowances are parameters
    tilted = _perturbed(pitch_deg=42.0)
    assert choose_ground(tilted, calibrated, max_angle_diff_deg=10.0) is tilted
    assert choose_ground(None, calibrated) is calibrated
    assert choose_ground(tilted, None) is tilted
    assert choose_ground(None, None) is None


def test_plane_from_coefficients_is_normalised_and_oriented() -> None:
    # the floor 2.5 m below an upright camera (optical y down), given upside down and scaled
    for coefficients in ((0.0, 4.0, 0.0, -10.0), (0.0, -2.0, 0.0, 5.0)):
        plane = GroundPlane.from_coefficients(coefficients)
        np.testing.assert_allclose(plane.coefficients, (0.0, -1.0, 0.0, 2.5), atol=1e-12)
        assert plane.source == "fixed"
        assert plane.height(np.array([[0.0, 2.5, 3.0]]))[0] == pytest.approx(0.0)
        assert plane.height(np.zeros((1, 3)))[0] == pytest.approx(2.5)
    for bad in ((0.0, 0.0, 0.0, 1.0), (math.nan, 1.0, 0.0, 1.0), (0.0, 1.0, 0.0, math.inf)):
        with pytest.raises(ConfigError, match="ground plane"):
            GroundPlane.from_coefficients(bad)


def test_ground_from_camera_puts_the_floor_at_zero() -> None:
    pose = Pose(x=1.0, y=2.0, z=2.6, yaw_deg=30.0, pitch_deg=35.0, roll_deg=10.0)
    plane = _truth(pose)
    ground = plane.ground_from_camera()
    np.testing.assert_allclose(apply(ground, np.zeros((1, 3)))[0], (0.0, 0.0, 2.6), atol=1e-9)
    rng = np.random.default_rng(0)
    world = np.column_stack([rng.uniform(2, 6, (50, 2)), rng.choice([0.0, 1.7], 50)])
    optical = apply(invert(world_from_optical(pose)), world)
    floor = apply(ground, optical)
    np.testing.assert_allclose(floor[:, 2], world[:, 2], atol=1e-9)  # heights kept
    # a rigid map: floor distances are the world's
    np.testing.assert_allclose(
        np.linalg.norm(floor[1:, :2] - floor[0, :2], axis=1),
        np.linalg.norm(world[1:, :2] - world[0, :2], axis=1),
        atol=1e-9,
    )
    # x runs forward along the optical axis
    ahead = apply(ground, np.array([[0.0, 0.0, 4.0]]))[0]
    assert ahead[0] > 0 and ahead[1] == pytest.approx(0.0, abs=1e-9)


# --------------------------------------------------------------------------- clustering

ROOM = Room(7.0, 10.0)
SENSOR = Pose(x=0.3, y=5.0, z=2.6, yaw_deg=0.0, pitch_deg=25.0)


def _two_heads_frames(count_per_seed: int, seeds: Sequence[int]):
    """Pairs of people whose heads are 0.4 m apart, side by side, in varied settings."""
    origin = np.array([SENSOR.x, SENSOR.y])
    for seed in seeds:
        renderer = _renderer(SENSOR, ROOM, seed=seed)
        rng = np.random.default_rng(1000 + seed)
        for _ in range(count_per_seed):
            distance = rng.uniform(2.0, 6.0)
            bearing = math.radians(rng.uniform(-25.0, 25.0))
            centre = origin + distance * np.array([math.cos(bearing), math.sin(bearing)])
            view = (centre - origin) / np.linalg.norm(centre - origin)
            lateral = np.array([-view[1], view[0]])
            turn = math.radians(rng.uniform(-60.0, 60.0))  # pair axis relative to the view
            axis = math.cos(turn) * lateral + math.sin(turn) * view
            heading = np.array([-axis[1], axis[0]]) * rng.choice([-1.0, 1.0])
            heights = rng.uniform(1.6, 1.9, 2)
            radii = rng.uniform(0.2, 0.25, 2)
            hues = rng.uniform(0, 360, 4)
            people = _snap(
                [
                    (*(centre - 0.2 * axis), heights[0], radii[0], hues[0], hues[1]),
                    (*(centre + 0.2 * axis), heights[1], radii[1], hues[2], hues[3]),
                ],
                t=rng.uniform(0.0, 2.0),  # walking phase
                vel=np.tile(rng.uniform(0.6, 1.3) * heading, (2, 1)),
            )
            yield seed, people, renderer.render(people)


def test_two_people_with_heads_0_4_m_apart_are_two_detections() -> None:
    hits = total = 0
    for seed, people, shot in _two_heads_frames(12, seeds=(0, 1, 2, 3)):
        result = _detector(SENSOR, seed=seed).detect(shot.frame)
        total += 1
        hits += _matches(_xy(result), people.pos, 0.3)
    rate = hits / total
    assert total >= 40
    assert rate >= 0.9, f"two detections in only {rate:.0%} of {total} frames"


@pytest.mark.parametrize("distance", [2.5, 4.0, 5.5])
def test_three_people_in_a_row_are_three_detections(distance: float) -> None:
    x = SENSOR.x + distance
    people = _snap(
        [(x, 4.5, 1.72, 0.22, 0, 200), (x, 5.0, 1.8, 0.23, 120, 40), (x, 5.5, 1.66, 0.21, 240, 90)]
    )
    for seed in (0, 1):
        shot = _renderer(SENSOR, ROOM, seed=seed).render(people)
        result = _detector(SENSOR, seed=seed).detect(shot.frame)
        assert _matches(_xy(result), people.pos, 0.3), _xy(result)


CABINET = Obstacle("cabinet", 3.5, 5.6, 4.1, 6.1, 1.95)
FURNISHED = Room(7.0, 10.0, obstacles=(CABINET,))


def test_a_cabinet_is_not_a_person_and_does_not_hide_one() -> None:
    alone = _renderer(SENSOR, FURNISHED).render(EMPTY)
    assert _detector(SENSOR).detect(alone.frame).detections == ()
    person = _snap([(3.8, 5.3, 1.75, 0.22, 30, 200)])  # a hand's breadth from its side
    for seed in (0, 1, 2):
        shot = _renderer(SENSOR, FURNISHED, seed=seed).render(person)
        result = _detector(SENSOR, seed=seed).detect(shot.frame)
        assert _matches(_xy(result), person.pos, 0.3), _xy(result)
        assert result.detections[0].height == pytest.approx(1.75, abs=0.1)


@pytest.mark.parametrize(
    ("kind", "pose", "room"),
    [
        ("kinect2", Pose(x=0.2, y=0.2, z=2.6, yaw_deg=45.0, pitch_deg=25.0), Room(6.0, 6.0)),
        ("kinect2", Pose(x=0.2, y=4.0, z=2.6, yaw_deg=0.0, pitch_deg=30.0), Room(8.0, 8.0)),
        ("kinect2", SENSOR, ROOM),
        ("kinect1", Pose(x=0.2, y=0.2, z=2.4, yaw_deg=40.0, pitch_deg=20.0), Room(6.0, 5.0)),
        ("realsense", Pose(x=5.8, y=4.8, z=2.5, yaw_deg=-140.0, pitch_deg=25.0), Room(6.0, 5.0)),
        ("sr4500", Pose(x=0.2, y=2.5, z=2.6, yaw_deg=0.0, pitch_deg=20.0), Room(6.0, 5.0)),
        ("kinect2", Pose(x=0.2, y=0.2, z=2.6, yaw_deg=40.0, pitch_deg=40.0), Room(6.0, 5.0)),
        ("kinect1", Pose(x=0.2, y=2.5, z=2.6, yaw_deg=0.0, pitch_deg=30.0), Room(8.0, 6.0)),
    ],
)
def test_walls_of_an_empty_room_are_not_people(kind: str, pose: Pose, room: Room) -> None:
    renderer = _renderer(pose, room, kind=kind)
    detector = _detector(pose, kind=kind)
    for _ in range(3):
        result = detector.detect(renderer.render(EMPTY).frame)
        assert result.ground is not None
        assert result.detections == (), _xy(result)


def test_the_child_preset_finds_children_and_the_adult_preset_does_not() -> None:
    children = _snap(
        [
            (2.8, 4.6, 1.0, 0.15, 60, 300),
            (3.6, 5.6, 1.0, 0.15, 180, 10),
            (4.5, 4.4, 1.05, 0.16, 0, 0),
        ],
        kind="child",
    )
    for seed in (0, 1):
        shot = _renderer(SENSOR, ROOM, seed=seed).render(children)
        child = _detector(SENSOR, DetectorConfig(preset="child"), seed=seed).detect(shot.frame)
        assert _matches(_xy(child), children.pos, 0.3), _xy(child)
        assert all(abs(d.height - 1.0) < 0.1 for d in child.detections)
        adult = _detector(SENSOR, seed=seed).detect(shot.frame)
        assert adult.detections == ()


# --------------------------------------------------------------------------- robustness

ONE = _snap([(3.5, 5.2, 1.78, 0.22, 10, 220)])


def test_holes_and_zeros_in_the_depth_do_not_lose_the_person() -> None:
    shot = _renderer(SENSOR, ROOM, seed=4).render(ONE)
    depth = shot.frame.depth.copy()
    rng = np.random.default_rng(4)
    pick = rng.permutation(depth.size)
    n = depth.size
    depth.ravel()[pick[: int(0.3 * n)]] = np.nan
    depth.ravel()[pick[int(0.3 * n) : int(0.4 * n)]] = 0.0
    frame = dataclasses.replace(shot.frame, depth=depth)
    result = _detector(SENSOR).detect(frame)
    assert result.status == "ok"
    assert _matches(_xy(result), ONE.pos, 0.15), _xy(result)


def test_a_steep_sensor_without_pose_or_floor_finds_everyone() -> None:
    pose = Pose(x=0.3, y=5.0, z=2.6, yaw_deg=0.0, pitch_deg=50.0, roll_deg=15.0)
    people = _snap(
        [
            (1.6, 4.6, 1.62, 0.21, 0, 100),
            (2.0, 5.3, 1.8, 0.23, 120, 200),
            (1.3, 5.8, 1.7, 0.22, 240, 0),
        ]
    )
    shot = _renderer(pose, ROOM, seed=2).render(people)
    assert (shot.head_visible == shot.head_pixels).all() and (shot.head_pixels > 0).all()
    config = DetectorConfig(ground=GroundConfig(mode="auto"))
    result = _detector(None, config, frame_id="overhead").detect(shot.frame)
    assert result.frame_id == "overhead"
    assert result.ground is not None and result.ground.offset == pytest.approx(2.6, abs=0.03)
    truth = _to_floor_frame(result, pose, people.pos)
    assert _matches(_xy(result), truth, 0.15), (_xy(result), truth)
    for d in result.detections:
        nearest = int(np.argmin(np.linalg.norm(truth - d.position[:2], axis=1)))
        assert d.height == pytest.approx(people.height[nearest], abs=0.1)


def test_an_all_nan_frame_gives_no_ground_and_no_detections() -> None:
    k = Intrinsics.for_sensor("kinect2")
    frame = Frame(0.0, 0, k, depth=np.full((k.height, k.width), np.nan, np.float32))
    for pose in (SENSOR, None):
        config = DetectorConfig(ground=GroundConfig(mode="auto"))
        result = _detector(pose, config).detect(frame)
        assert result.detections == () and result.status == "no-ground"
        assert result.ground is None


def test_an_unorganised_cloud_is_detected() -> None:
    shot = _renderer(SENSOR, ROOM, seed=6).render(ONE)
    k = shot.frame.intrinsics
    v, u = np.nonzero(np.isfinite(shot.frame.depth))
    frame = Frame(
        1.0,
        1,
        None,
        points=_optical_points(shot.frame).astype(np.float32),
        point_colors=shot.frame.color[v, u],
    )
    assert k is not None and frame.depth is None
    result = _detector(SENSOR).detect(frame)
    assert result.status == "ok"
    assert _matches(_xy(result), ONE.pos, 0.15), _xy(result)
    (person,) = result.detections
    assert person.height == pytest.approx(1.78, abs=0.08)
    assert abs(sum(person.appearance) - 255) <= 8  # colours went into the signature
    assert person.bbox == (0, 0, 0, 0)  # no image to box


@pytest.mark.parametrize("ascii_pcd", [True, False])
def test_a_pcd_cloud_in_the_optical_frame_is_detected(tmp_path: Path, ascii_pcd: bool) -> None:
    o3d = pytest.importorskip("open3d")
    from openptrack_py.detection.sources import CloudSource, open_source

    people = _snap(
        [
            (2.8, 4.4, 1.65, 0.21, 0, 100),
            (3.9, 5.4, 1.85, 0.24, 120, 200),
            (5.0, 4.6, 1.72, 0.22, 240, 0),
        ]
    )
    shot = _renderer(SENSOR, ROOM, seed=8).render(people)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(_optical_points(shot.frame)))
    path = tmp_path / "people.pcd"
    assert o3d.io.write_point_cloud(str(path), cloud, write_ascii=ascii_pcd)
    source = open_source(str(path))
    assert isinstance(source, CloudSource)
    frame = next(iter(source.frames()))
    assert frame.depth is None and len(frame.points) == np.isfinite(shot.frame.depth).sum()
    config = DetectorConfig(ground=GroundConfig(mode="auto"))
    result = _detector(None, config).detect(frame)
    assert result.frame_id == "cam"
    found = _xy(result)
    truth = _to_floor_frame(result, SENSOR, people.pos)
    assert _matches(found, truth, 0.15), (found, truth)
    # the same geometry without any frame mapping: pairwise distances agree
    order = [int(np.argmin(np.linalg.norm(found - p, axis=1))) for p in truth]
    pair_found = np.linalg.norm(found[order][:, None] - found[order][None], axis=2)
    pair_truth = np.linalg.norm(people.pos[:, None] - people.pos[None], axis=2)
    np.testing.assert_allclose(pair_found, pair_truth, atol=0.15)
    heights = np.array([result.detections[i].height for i in order])
    np.testing.assert_allclose(heights, people.height, atol=0.1)


# --------------------------------------------------------------------------- background


def _world_cloud(shot: RenderedFrame, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
    """World points of a rendered frame's valid pixels, and their labels."""
    mask = np.isfinite(shot.frame.depth)
    world = apply(world_from_optical(pose), _optical_points(shot.frame))
    return world, shot.labels[mask]


def test_background_model_removes_the_learned_room_only() -> None:
    renderer = _renderer(SENSOR, FURNISHED, seed=9)
    model = BackgroundModel(resolution_m=0.1, learn_frames=3)
    for _ in range(3):
        assert model.learning
        model.learn(_world_cloud(renderer.render(EMPTY), SENSOR)[0])
    assert not model.learning and model.voxels > 1000
    points, labels = _world_cloud(renderer.render(_snap([(3.8, 5.3, 1.75, 0.22, 0, 0)])), SENSOR)
    keep = model.foreground(points)
    assert keep[labels == 0].mean() > 0.9  # the person stays
    assert keep[labels < 0].mean() < 0.03  # the room goes
    assert BackgroundModel().foreground(points).all()  # nothing learned: nothing removed


def test_detector_learns_the_background_then_finds_a_cabinet_hugger() -> None:
    config = DetectorConfig(background=BackgroundConfig(enabled=True, seconds=0.1))
    detector = PeopleDetector(
        config, world_from_camera=world_from_optical(SENSOR), sensor_type="kinect2", rate_hz=30
    )
    renderer = _renderer(SENSOR, FURNISHED, seed=10)
    statuses = [detector.detect(renderer.render(EMPTY).frame).status for _ in range(3)]
    assert statuses == ["learning-background"] * 3
    hugger = _snap([(3.8, 5.36, 1.7, 0.22, 300, 60)])  # touching the cabinet's front
    for _ in range(3):
        result = detector.detect(renderer.render(hugger).frame)
        assert result.status == "ok"
        assert _matches(_xy(result), hugger.pos, 0.3), _xy(result)
    assert detector.detect(renderer.render(EMPTY).frame).detections == ()


# --------------------------------------------------------------------------- appearance


def test_hue_histograms_of_pure_colours() -> None:
    rgb = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [128, 128, 128], [9, 9, 200]] * 20)
    labels = np.array([0, 1, 2, 3, -1] * 20)
    hist = hue_histograms(rgb.astype(np.uint8), labels, 4, bins=16)
    assert hist.shape == (4, 16) and hist.dtype == np.uint8
    assert int(np.argmax(hist[0])) == 0  # red: 0 degrees
    assert int(np.argmax(hist[1])) == 5  # green: 120 degrees, 16 bins of 22.5
    assert int(np.argmax(hist[2])) == 10  # blue: 240 degrees
    for row in hist[:3]:
        assert row.max() == 255 and int(row.sum()) == 255
    assert (hist[3] == 0).all()  # grey has no hue
    mixed = hue_histograms(rgb[:2].astype(np.uint8), np.array([0, 0]), 1, bins=16)[0]
    assert mixed[0] == mixed[5] and abs(int(mixed.sum()) - 255) <= 1  # half and half
    assert hue_histograms(rgb.astype(np.uint8), np.full(len(rgb), -1), 2).sum() == 0


# Bins of the 16 + 3 signature: hue sectors of 22.5 degrees, then dark, grey, light.
_DARK, _GREY, _LIGHT = 16, 17, 18


def test_colour_signatures_have_hue_bins_then_dark_grey_and_light() -> None:
    pixels = {
        0: (255, 0, 0),  # red: hue bin 0
        1: (0, 160, 0),  # green: 120 degrees, bin 5
        2: (20, 20, 120),  # navy: 240 degrees, bin 10
        3: (12, 10, 14),  # black: dark
        4: (128, 128, 128),  # grey
        5: (240, 238, 236),  # white: light
        6: (200, 190, 182),  # greige: too little saturation for a hue, light
        7: (40, 40, 40),  # charcoal: below the hue's value floor, dark
    }
    rgb = np.array([pixels[k] for k in sorted(pixels)] * 10, dtype=np.uint8)
    labels = np.array(sorted(pixels) * 10)
    sig = colour_signatures(rgb, labels, 9, bins=16)
    assert sig.shape == (9, 16 + ACHROMATIC_BINS) and sig.dtype == np.uint8
    expected = [0, 5, 10, _DARK, _GREY, _LIGHT, _LIGHT, _DARK]
    assert [int(np.argmax(row)) for row in sig[:8]] == expected
    for row in sig[:8]:
        assert row.max() == 255 and int(row.sum()) == 255
    assert (sig[8] == 0).all()  # no samples: no signature
    # a red top over black trousers: half hue, half dark
    mixed = colour_signatures(rgb[[0, 3]], np.array([0, 0]), 1)[0]
    assert mixed[0] == mixed[_DARK] and abs(int(mixed.sum()) - 255) <= 1
    # the hue-only histogram of the same pixels still ignores what has no hue
    assert (hue_histograms(rgb, labels, 9, bins=16)[3:8] == 0).all()
    # other hue resolutions keep three achromatic bins at the end
    eight = colour_signatures(rgb, labels, 9, bins=8)
    assert eight.shape == (9, 11) and int(np.argmax(eight[4])) == 9


def test_signature_bins_agree_with_the_rgb_path() -> None:
    rng = np.random.default_rng(3)
    rgb = rng.integers(0, 256, (500, 3)).astype(np.uint8)
    hsv = rgb_to_hsv(rgb)
    assert hsv[:, 0].min() >= 0 and hsv[:, 0].max() < 360
    which = signature_bins(hsv[:, 0], hsv[:, 1], hsv[:, 2], bins=16)
    sig = colour_signatures(rgb, np.arange(500), 500, bins=16)
    assert (np.argmax(sig, axis=1) == which).all()
    # hue wraps: -10 degrees is the last sector, 370 the first
    assert signature_bins(np.array([-10.0, 370.0]), np.ones(2), np.ones(2)).tolist() == [15, 0]


def test_bhattacharyya_compares_signatures_of_one_length() -> None:
    a = np.array([255, 0, 0, 0])
    b = np.array([0, 0, 128, 127])
    assert bhattacharyya(a, a) == pytest.approx(1.0)
    assert bhattacharyya(a, b) == 0.0
    assert bhattacharyya(np.zeros(4), a) == 0.0
    assert 0.0 < bhattacharyya(np.array([128, 127, 0, 0]), a) < 1.0
    with pytest.raises(ValueError, match="differ"):
        bhattacharyya(a, np.zeros(5))


@pytest.mark.parametrize(
    ("saturation", "value", "bin_"),
    [(0.05, 0.1, _DARK), (0.03, 0.55, _GREY), (0.04, 0.92, _LIGHT)],
    ids=["black", "grey", "white"],
)
def test_detector_signature_sees_black_grey_and_white_clothes(
    saturation: float, value: float, bin_: int
) -> None:
    """The real detector on a rendered person: achromatic tops fill achromatic bins."""
    person = dataclasses.replace(
        ONE, top_saturation=np.array([saturation]), top_value=np.array([value])
    )
    shot = _renderer(SENSOR, ROOM, seed=2).render(person)
    (found,) = _detector(SENSOR, seed=2).detect(shot.frame).detections
    sig = np.array(found.appearance)
    assert len(sig) == 16 + ACHROMATIC_BINS
    assert sig[bin_] > 0.6 * sig.sum()
    assert sig[:16].sum() < 0.25 * sig.sum()  # skin and hair only


def test_appearance_tells_people_apart_by_their_clothes() -> None:
    def signature(person: tuple[float, ...], seed: int, t: float) -> np.ndarray:
        shot = _renderer(SENSOR, ROOM, seed=seed).render(_snap([person], t=t))
        (found,) = _detector(SENSOR, seed=seed).detect(shot.frame).detections
        return np.array(found.appearance)

    red_blue = signature((3.5, 5.0, 1.75, 0.22, 0.0, 230.0), 1, 0.0)
    again = signature((4.2, 4.3, 1.75, 0.22, 0.0, 230.0), 2, 0.6)
    green_purple = signature((3.5, 5.0, 1.75, 0.22, 120.0, 290.0), 1, 0.0)
    same = hue_correlation(red_blue, again)
    other = hue_correlation(red_blue, green_purple)
    assert same > 0.8
    assert other < same - 0.5
    assert hue_correlation(red_blue, red_blue) == pytest.approx(1.0)
    assert hue_correlation(np.zeros(16), red_blue) == 0.0


# --------------------------------------------------------------------------- HOG


def test_hog_verifier_scores_and_confidence_scale() -> None:
    pytest.importorskip("cv2")
    from openptrack_py.detection.hog import HogVerifier, margin_to_confidence

    hog = HogVerifier()
    gray = np.full((240, 320), 128, np.uint8)
    scores = hog.score(gray, [(100, 40, 50, 120), (0, 0, 1, 1)])
    assert math.isfinite(scores[0]) and scores[1] == -math.inf
    assert margin_to_confidence(0.0) == 0.5
    conf = margin_to_confidence(np.array([-50.0, -1.0, 1.0, 50.0]))
    assert (np.diff(conf) > 0).all() and conf.min() >= 0.0 and conf.max() <= 1.0


def _hog_result(config: HogConfig, frame: Frame, kind: str = "kinect2") -> DetectionResult:
    return _detector(SENSOR, DetectorConfig(hog=config), kind=kind).detect(frame)


def test_hog_check_follows_the_luminance_rule_and_the_image_choice() -> None:
    pytest.importorskip("cv2")
    shot = _renderer(SENSOR, ROOM, seed=12).render(ONE)
    plain = _detector(SENSOR).detect(shot.frame)
    assert plain.hog == "off" and len(plain.detections) == 1
    dark = dataclasses.replace(shot.frame, color=(shot.frame.color // 16).astype(np.uint8))
    result = _hog_result(HogConfig(enabled=True, image="color"), dark)
    assert result.hog == "dark"
    assert [d.position for d in result.detections] == [d.position for d in plain.detections]
    ir = _hog_result(HogConfig(enabled=True, image="ir"), shot.frame)
    assert ir.hog == "ir"
    auto_tof = _hog_result(HogConfig(enabled=True), shot.frame)
    assert auto_tof.hog == "ir"  # Kinect v2 is time-of-flight
    colour = _hog_result(HogConfig(enabled=True, image="color"), shot.frame)
    assert colour.hog == "color"
    for res in (ir, auto_tof, colour, result):
        for d in res.detections:
            assert 0.0 <= d.confidence <= 1.0
            assert (d.hog_margin is None) == (res.hog == "dark")


# --------------------------------------------------------------------------- evaluation


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["crowd", "classroom"])
def test_detector_evaluation_floor(scenario: str) -> None:
    score = evaluate_detector(scenario, sensor_type="kinect2", duration_s=6, sample_hz=1)
    assert score["expected"] > 20
    assert score["recall"] >= 0.95
    assert score["precision"] >= 0.95
    assert score["mean_error_m"] <= 0.10


def test_detect_command_reads_a_kinect_style_pcd_without_pose(tmp_path: Path) -> None:
    """``openptrack detect cloud.pcd --ground auto --format json`` as a user runs it."""
    o3d = pytest.importorskip("open3d")
    people = _snap([(2.8, 4.4, 1.65, 0.21, 0, 100), (4.2, 5.6, 1.85, 0.24, 120, 200)])
    shot = _renderer(SENSOR, ROOM, seed=9).render(people)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(_optical_points(shot.frame)))
    path = tmp_path / "kinect.pcd"
    assert o3d.io.write_point_cloud(str(path), cloud)
    run = subprocess.run(
        [sys.executable, "-m", "openptrack_py.cli", "detect", str(path), "--ground", "auto",
         "--format", "json"],
        capture_output=True, text=True, timeout=120, env=python_env(), cwd=ROOT,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    (record,) = [json.loads(line) for line in run.stdout.splitlines()]
    assert record["status"] == "ok" and record["ground_source"] == "auto"
    *normal, offset = record["ground"]
    truth = GroundPlane.from_world_pose(world_from_optical(SENSOR))
    assert offset == pytest.approx(SENSOR.z, abs=0.03)  # the camera's height above the floor
    assert math.degrees(math.acos(min(1.0, float(np.dot(normal, truth.normal))))) < 1.0
    heights = sorted(det["height"] for det in record["detections"])
    np.testing.assert_allclose(heights, sorted(people.height), atol=0.1)
    found = np.array([det["position"][:2] for det in record["detections"]])
    gap = np.linalg.norm(people.pos[0] - people.pos[1])
    assert np.linalg.norm(found[0] - found[1]) == pytest.approx(gap, abs=0.15)
    for det in record["detections"]:  # optical frame: z forward, the same range
        assert det["sensor_position"][2] > 0
        assert np.linalg.norm(det["sensor_position"]) == pytest.approx(det["distance"], abs=1e-3)


# ------------------------------------------------------------------ lens distortion


KINECT2_FACTORY_LENS = (0.0905, -0.2706, 0.0012, -0.0008, 0.0967)
"""A Kinect v2 infrared camera's five lens terms ``k1, k2, p1, p2, k3`` of the size its
driver (libfreenect2) reports: strong radial terms, the tangential ones a thousandth."""


@pytest.mark.parametrize("lens", [(-0.15, 0.05, 0.0, 0.0, 0.0), KINECT2_FACTORY_LENS])
def test_intrinsics_rays_invert_the_lens_as_opencv_does(lens: tuple[float, ...]) -> None:
    cv2 = pytest.importorskip("cv2")
    k = Intrinsics.for_sensor("kinect2").with_distortion(lens)
    rng = np.random.default_rng(4)
    u, v = rng.uniform(0, k.width, 200), rng.uniform(0, k.height, 200)
    x, y = k.rays(u, v)
    # OpenCV's projection of each ray lands back on its pixel ...
    rays = np.column_stack([x, y, np.ones_like(x)])
    back, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), k.matrix, np.array(lens))
    np.testing.assert_allclose(back.reshape(-1, 2), np.column_stack([u, v]), atol=1e-6)
    # ... and OpenCV's own inversion, iterated to convergence, agrees
    pts = np.column_stack([u, v]).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    oracle = cv2.undistortPointsIter(pts, k.matrix, np.array(lens), None, None, criteria)
    np.testing.assert_allclose(np.column_stack([x, y]), oracle.reshape(-1, 2), atol=1e-7)
    # the lens is kept through a change of image size and through a file
    assert k.scaled(256, 212).distortion == k.distortion == lens
    assert Intrinsics.from_dict(k.to_dict()) == k
    assert "k1" not in Intrinsics.for_sensor("kinect2").to_dict()  # files as before
    with pytest.raises(ConfigError, match=r"intrinsics\.k1"):
        Intrinsics(512, 424, 360.0, 360.0, 256.0, 212.0, k1=math.nan)
    # projecting a ray through the lens lands back on its pixel
    pu, pv = k.pixels(np.column_stack([x, y, np.ones_like(x)]))
    np.testing.assert_allclose(np.column_stack([pu, pv]), np.column_stack([u, v]), atol=1e-6)
    # a lens whose model stops growing inside the image cannot be inverted there: the
    # corners see nothing rather than somewhere wrong, and the detector still runs
    folded = dataclasses.replace(Intrinsics.for_sensor("kinect2"), k2=-0.15)
    x, _ = folded.rays(np.array([0.0, 256.0]), np.array([0.0, 212.0]))
    assert np.isnan(x[0]) and np.isfinite(x[1])
    frame = Frame(0.0, 0, folded, depth=np.full((424, 512), 3.0, dtype=np.float32))
    detector = PeopleDetector(
        DetectorConfig(), sensor_type="kinect2", rng=np.random.default_rng(0)
    )
    assert detector.detect(frame).detections == ()  # a flat wall: nobody, and no error


@pytest.mark.parametrize(
    "lens",
    [
        (-0.15, 0.05, 0.0, 0.0, 0.0),
        (0.12, -0.05, 0.0, 0.0, 0.0),
        (-0.12, 0.04, 0.004, -0.004, 0.02),  # decentred: a cheaper lens, mounted off-axis
    ],
)
def test_a_distorted_depth_image_is_detected_through_its_lens(lens: tuple[float, ...]) -> None:
    """Two people near the image's sides, seen through a distorting lens (the pinhole
    rendering remapped by OpenCV's model): through the pinhole alone both are 3-6.5 cm
    off, through the camera model with the lens within 1.5 cm."""
    cv2 = pytest.importorskip("cv2")
    pose = Pose(x=0.2, y=4.0, z=2.6, yaw_deg=0.0, pitch_deg=22.0)
    people = ((3.2, 5.6, 1.75, 0.22, 10.0, 200.0), (3.6, 2.3, 1.65, 0.20, 120.0, 60.0))
    frame = _renderer(pose, Room(10.0, 8.0)).render(_snap(people), stamp=0.0, seq=0).frame
    pinhole = Intrinsics.for_sensor("kinect2")
    grid = np.mgrid[0 : pinhole.height, 0 : pinhole.width][::-1].reshape(2, -1).T
    # where each pixel of the distorted image looks, in the pinhole image
    source = cv2.undistortPoints(
        grid.reshape(-1, 1, 2).astype(np.float64), pinhole.matrix, np.array(lens),
        P=pinhole.matrix,
    ).reshape(pinhole.height, pinhole.width, 2).astype(np.float32)  # fmt: skip
    warp = {"interpolation": cv2.INTER_NEAREST, "borderMode": cv2.BORDER_CONSTANT}
    distorted = dataclasses.replace(
        frame,
        depth=cv2.remap(frame.depth, source[..., 0], source[..., 1], borderValue=np.nan, **warp),
        color=cv2.remap(frame.color, source[..., 0], source[..., 1], **warp),
    )
    truth = np.array([p[:2] for p in people])
    errors = {}
    for name, k in (("pinhole", pinhole), ("lens", pinhole.with_distortion(lens))):
        detector = PeopleDetector(
            DetectorConfig(), world_from_camera=world_from_optical(pose), sensor_type="kinect2",
            rng=np.random.default_rng(0),
        )  # fmt: skip
        found = detector.detect(dataclasses.replace(distorted, intrinsics=k)).detections
        assert len(found) == 2, name
        xy = np.array([d.position[:2] for d in found])
        errors[name] = np.linalg.norm(xy[:, None] - truth[None], axis=2).min(axis=0)
    assert errors["pinhole"].min() > 0.03, errors
    assert errors["lens"].max() < 0.015, errors


def test_an_image_box_through_a_lens_covers_what_lies_beyond_its_fold() -> None:
    """A lens's model turns back towards the centre beyond its fold (here 52 degrees off
    the axis): an object reaching past it projects partly inside the image although it
    covers the image's edge, so its box is the whole image; one inside stays tight."""
    k = Intrinsics.for_sensor("kinect2").with_distortion((0.12, -0.072, 0.0, 0.0, -0.02))
    corners = [(x, y, 1.0) for x in (0.31, 3.08) for y in (-0.1, 0.1)]  # 17-72 degrees
    assert image_box(np.array(corners), k) == (0, k.width, 0, k.height)
    near = np.array([(x, y, 1.0) for x in (0.1, 0.3) for y in (-0.1, 0.1)])
    u0, u1, v0, v1 = image_box(near, k)
    u, v = k.pixels(near)
    assert u0 <= u.min() and u.max() < u1 <= u.max() + 5 and v0 <= v.min() and v.max() < v1
