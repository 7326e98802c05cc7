"""Tests for openptrack_py.sim.render: what a simulated depth camera delivers.

The empty room is checked against an independent ray cast (the exit point of every
pixel's ray from the room's box), the noise models against their per-type laws, and
rendered people against where they stand and what they wear. Every run is seeded.
"""

from __future__ import annotations

import numpy as np
import pytest

from openptrack_py.config import Pose, SensorConfig
from openptrack_py.detection.frame import Intrinsics
from openptrack_py.geometry import world_from_optical
from openptrack_py.sensor_types import SENSOR_TYPES
from openptrack_py.sim.render import DEPTH_NOISE, WALL_HEIGHT_M, DepthRenderer, RenderedFrame
from openptrack_py.sim.sensors import SensorSpec
from openptrack_py.sim.world import Room
from tests.conftest import people_snapshot

SIZES = {
    "kinect1": (320, 240),
    "kinect2": (512, 424),
    "realsense": (640, 480),
    "sr4500": (176, 144),
}

# --------------------------------------------------------------------------- helpers


_snap = people_snapshot


EMPTY = _snap([])


def _spec(kind: str, pose: Pose) -> SensorSpec:
    return SensorSpec.from_config(SensorConfig(id="cam", type=kind, pose=pose))  # type: ignore[arg-type]


def _renderer(
    kind: str, pose: Pose, room: Room, *, seed: int = 0, noise: bool = True
) -> DepthRenderer:
    return DepthRenderer(_spec(kind, pose), room, np.random.default_rng(seed), noise=noise)


def _rays(k: Intrinsics) -> np.ndarray:
    """Optical-frame ray per pixel, scaled to unit depth."""
    u, v = np.meshgrid(np.arange(k.width), np.arange(k.height))
    return np.stack([(u - k.cx) / k.fx, (v - k.cy) / k.fy, np.ones(u.shape)], axis=-1)


def _analytic_room(k: Intrinsics, pose: Pose, room: Room) -> tuple[np.ndarray, np.ndarray]:
    """Depth of the empty room per pixel, and which surface each pixel sees.

    Surfaces: 0 floor, 1 ceiling, 2 wall x=0, 3 wall x=width, 4 wall y=0, 5 wall y=depth.
    The camera is inside the box, so a ray leaves it through the nearest face ahead.
    """
    pose_m = world_from_optical(pose)
    d = _rays(k) @ pose_m[:3, :3].T
    o = pose_m[:3, 3]
    bounds = [(2, 0.0), (2, WALL_HEIGHT_M), (0, 0.0), (0, room.width), (1, 0.0), (1, room.depth)]
    ts = []
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis, coord in bounds:
            t = (coord - o[axis]) / d[..., axis]
            ts.append(np.where(t > 0, t, np.inf))
    ts = np.stack(ts, axis=-1)
    return ts.min(axis=-1), ts.argmin(axis=-1)


def _world_points(frame_depth: np.ndarray, k: Intrinsics, pose: Pose) -> np.ndarray:
    """``(h, w, 3)`` world points of a depth image (NaN where the depth is)."""
    pts = _rays(k) * frame_depth[..., None]
    pose_m = world_from_optical(pose)
    return pts @ pose_m[:3, :3].T + pose_m[:3, 3]


def _hue_deg(rgb: np.ndarray) -> np.ndarray:
    """Hue in degrees of ``(n, 3)`` uint8 RGB samples."""
    c = rgb.astype(float) / 255.0
    mx, mn = c.max(axis=1), c.min(axis=1)
    chroma = np.maximum(mx - mn, 1e-9)
    r, g, b = c.T
    h = np.where(
        mx == r,
        ((g - b) / chroma) % 6,
        np.where(mx == g, (b - r) / chroma + 2, (r - g) / chroma + 4),
    )
    return 60.0 * h


def _circular_mean_deg(angles: np.ndarray) -> float:
    a = np.radians(angles)
    return float(np.degrees(np.arctan2(np.sin(a).mean(), np.cos(a).mean())) % 360.0)


def _angle_diff(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


# --------------------------------------------------------------------------- empty room

ROOM = Room(6.0, 5.0)
POSE = Pose(x=0.3, y=1.8, z=2.4, yaw_deg=25.0, pitch_deg=30.0, roll_deg=4.0)


@pytest.mark.parametrize("kind", sorted(SIZES))
def test_frame_size_and_intrinsics_per_sensor_type(kind: str) -> None:
    shot = _renderer(kind, POSE, ROOM).render(EMPTY, stamp=12.5, seq=7)
    frame = shot.frame
    width, height = SIZES[kind]
    assert frame.intrinsics == Intrinsics.for_sensor(kind)
    assert (frame.intrinsics.width, frame.intrinsics.height) == (width, height)
    assert frame.depth.shape == (height, width)
    assert frame.depth.dtype == np.float32
    assert frame.color.shape == (height, width, 3) and frame.color.dtype == np.uint8
    assert frame.intensity.shape == (height, width)
    assert shot.labels.shape == (height, width) and (shot.labels == -1).all()
    assert (frame.stamp, frame.seq) == (12.5, 7)
    # the intrinsics follow the type's field of view
    spec = SENSOR_TYPES[kind]
    hfov = 2 * np.degrees(np.arctan(width / 2 / frame.intrinsics.fx))
    vfov = 2 * np.degrees(np.arctan(height / 2 / frame.intrinsics.fy))
    assert hfov == pytest.approx(spec.hfov_deg) and vfov == pytest.approx(spec.vfov_deg)


@pytest.mark.parametrize("kind", sorted(SIZES))
def test_noiseless_empty_room_matches_the_analytic_room(kind: str) -> None:
    """Floor pixels back-project onto z = 0, wall pixels onto their wall."""
    renderer = _renderer(kind, POSE, ROOM, noise=False)
    frame = renderer.render(EMPTY).frame
    k = frame.intrinsics
    depth, surface = _analytic_room(k, POSE, ROOM)
    range_m = depth * np.linalg.norm(_rays(k), axis=-1)
    limits = SENSOR_TYPES[kind]
    in_range = (range_m >= limits.min_range_m) & (range_m <= limits.max_range_m)
    assert in_range.mean() > 0.9
    # every in-range pixel has a reading, equal to the analytic depth
    assert np.isfinite(frame.depth[in_range]).all()
    np.testing.assert_allclose(frame.depth[in_range], depth[in_range], rtol=2e-6, atol=1e-6)
    world = _world_points(frame.depth.astype(np.float64), k, POSE)
    coords = {0: (2, 0.0), 2: (0, 0.0), 3: (0, ROOM.width), 4: (1, 0.0), 5: (1, ROOM.depth)}
    seen = 0
    for index, (axis, coord) in coords.items():
        mask = in_range & (surface == index)
        if not mask.any():
            continue
        seen += 1
        assert np.abs(world[mask][:, axis] - coord).max() < 1e-4, index
        # and inside the room on the other axes
        assert (world[mask][:, 2] > -1e-4).all() and (
            world[mask][:, 2] < WALL_HEIGHT_M + 1e-4
        ).all()
    assert (in_range & (surface == 0)).sum() > 0.2 * depth.size  # plenty of floor
    assert seen >= 3  # the floor and at least two walls


# --------------------------------------------------------------------------- noise

NOISE_POSE = Pose(x=0.3, y=2.5, z=1.2, yaw_deg=0.0, pitch_deg=35.0)
LONG_ROOM = Room(14.0, 5.0)


def _floor_noise(kind: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Clean floor depth, noisy minus clean, and the floor mask of an empty long room."""
    clean = _renderer(kind, NOISE_POSE, LONG_ROOM, noise=False).render(EMPTY).frame
    noisy = _renderer(kind, NOISE_POSE, LONG_ROOM, seed=3).render(EMPTY).frame
    _, surface = _analytic_room(clean.intrinsics, NOISE_POSE, LONG_ROOM)
    floor = (surface == 0) & np.isfinite(clean.depth) & np.isfinite(noisy.depth)
    return clean.depth, noisy.depth - clean.depth, floor


def _spread(clean: np.ndarray, diff: np.ndarray, floor: np.ndarray, at: float) -> float:
    mask = floor & (np.abs(clean - at) < 0.1)
    assert mask.sum() > 500
    return float(np.std(diff[mask]))


def test_kinect1_noise_grows_with_distance_squared() -> None:
    clean, diff, floor = _floor_noise("kinect1")
    near, far = _spread(clean, diff, floor, 1.5), _spread(clean, diff, floor, 3.0)
    # sigma = 1.4e-3 z^2 plus disparity steps that also grow with z^2: about 4x at twice the
    # distance (linear growth would give 2x, constant 1x)
    assert 3.0 < far / near < 5.5
    assert 0.002 < near < 0.008


def test_kinect2_noise_is_nearly_constant() -> None:
    clean, diff, floor = _floor_noise("kinect2")
    near, far = _spread(clean, diff, floor, 1.5), _spread(clean, diff, floor, 3.0)
    assert 0.9 < far / near < 1.7
    assert 0.0015 < near < 0.005


@pytest.mark.parametrize("kind", ["kinect1", "kinect2"])
def test_readings_beyond_the_maximum_range_are_missing(kind: str) -> None:
    pose = Pose(x=0.3, y=2.5, z=2.0, yaw_deg=0.0, pitch_deg=5.0)
    frame = _renderer(kind, pose, LONG_ROOM, seed=1).render(EMPTY).frame
    depth, _ = _analytic_room(frame.intrinsics, pose, LONG_ROOM)
    max_range = SENSOR_TYPES[kind].max_range_m
    beyond = depth > max_range + 0.3  # the depth (so also the range) is past the limit
    near = depth * np.linalg.norm(_rays(frame.intrinsics), axis=-1) < max_range - 0.5
    assert beyond.sum() > 1000 and near.sum() > 1000
    assert np.isnan(frame.depth[beyond]).all()
    assert np.isfinite(frame.depth[near]).mean() > 0.9


@pytest.mark.parametrize("kind", ["kinect1", "realsense", "sr4500"])
def test_a_fraction_of_valid_pixels_drops_out(kind: str) -> None:
    """Away from grazing angles and depth edges, about ``dropout`` of the pixels read NaN."""
    clean = _renderer(kind, POSE, ROOM, noise=False).render(EMPTY).frame
    noisy = _renderer(kind, POSE, ROOM, seed=5).render(EMPTY).frame
    k = clean.intrinsics
    _, surface = _analytic_room(k, POSE, ROOM)
    rays = _rays(k) @ world_from_optical(POSE)[:3, :3].T
    cos_floor = np.abs(rays[..., 2]) / np.linalg.norm(rays, axis=-1)
    steep = (surface == 0) & (cos_floor > 0.5) & np.isfinite(clean.depth)
    assert steep.sum() > 3000
    lost = float(np.isnan(noisy.depth[steep]).mean())
    dropout = DEPTH_NOISE[kind].dropout
    assert 0.6 * dropout < lost < 1.6 * dropout
    assert not np.isnan(clean.depth[steep]).any()


# --------------------------------------------------------------------------- people

PERSON_POSE = Pose(x=0.3, y=2.5, z=2.6, yaw_deg=0.0, pitch_deg=25.0)
ALICE = (3.5, 2.5, 1.75, 0.22, 210.0, 30.0)  # blue-ish top, orange-ish trousers
BOB = (2.0, 2.45, 1.8, 0.23, 100.0, 300.0)  # right between Alice and the sensor


def _person_renderer(seed: int = 0, noise: bool = False) -> DepthRenderer:
    return _renderer("kinect2", PERSON_POSE, ROOM, seed=seed, noise=noise)


def test_a_lone_person_is_labelled_and_fully_visible() -> None:
    shot = _person_renderer().render(_snap([ALICE]))
    assert (shot.labels == 0).sum() > 2000
    assert set(np.unique(shot.labels)) == {-1, 0}
    assert shot.visible_pixels[0] == (shot.labels == 0).sum()
    assert shot.visible_pixels[0] == shot.body_pixels[0]
    assert shot.head_pixels[0] > 100
    assert shot.head_visible[0] == shot.head_pixels[0]
    assert list(shot.ids) == [1]


def test_a_person_in_front_hides_the_one_behind() -> None:
    alone = _person_renderer().render(_snap([ALICE]))
    both = _person_renderer().render(_snap([ALICE, BOB]))
    assert both.body_pixels[0] == alone.body_pixels[0]  # what would show without Bob
    assert both.visible_pixels[0] < 0.7 * alone.visible_pixels[0]
    assert both.visible_pixels[1] == both.body_pixels[1]  # nobody in front of Bob
    for row in (0, 1):
        assert both.visible_pixels[row] == (both.labels == row).sum()
    # where Bob now shows, Alice used to
    assert (alone.labels[both.labels == 1] == 0).sum() > 1000


def _labelled_world(shot: RenderedFrame, row: int) -> tuple[np.ndarray, np.ndarray]:
    """World points and colours of one person's pixels."""
    frame = shot.frame
    world = _world_points(frame.depth.astype(np.float64), frame.intrinsics, PERSON_POSE)
    mask = (shot.labels == row) & np.isfinite(frame.depth)
    return world[mask], frame.color[mask]


def test_torso_wears_the_top_hue_and_legs_the_bottom_hue() -> None:
    shot = _person_renderer().render(_snap([ALICE]))
    pts, rgb = _labelled_world(shot, 0)
    x, y, height, radius, top_hue, bottom_hue = ALICE
    lateral = np.hypot(pts[:, 0] - x, pts[:, 1] - y)
    torso = (pts[:, 2] > 0.6 * height) & (pts[:, 2] < 0.72 * height) & (lateral < 0.6 * radius)
    legs = (pts[:, 2] > 0.1 * height) & (pts[:, 2] < 0.4 * height)
    assert torso.sum() > 100 and legs.sum() > 100
    assert _angle_diff(_circular_mean_deg(_hue_deg(rgb[torso])), top_hue) < 20
    assert _angle_diff(_circular_mean_deg(_hue_deg(rgb[legs])), bottom_hue) < 20


def test_person_depth_lies_on_the_near_side_of_the_body() -> None:
    """Labelled pixels lie within the person's cylinder, in front of the empty room."""
    empty = _person_renderer().render(EMPTY)
    shot = _person_renderer().render(_snap([ALICE]))
    mask = shot.labels == 0
    assert (shot.frame.depth[mask] < empty.frame.depth[mask]).all()
    pts, _ = _labelled_world(shot, 0)
    x, y, height, radius, _, _ = ALICE
    lateral = np.hypot(pts[:, 0] - x, pts[:, 1] - y)
    assert lateral.max() < 1.3 * radius  # arms hang at most ~1.25 radii out
    assert pts[:, 2].min() > -1e-3 and pts[:, 2].max() < height + 1e-3
    sensor = np.array([PERSON_POSE.x, PERSON_POSE.y, PERSON_POSE.z])
    centre = np.column_stack([np.full(len(pts), x), np.full(len(pts), y), pts[:, 2]])
    to_point = np.linalg.norm(pts - sensor, axis=1)
    to_centre = np.linalg.norm(centre - sensor, axis=1)
    assert (to_point > 0.5).all()
    assert (to_point <= to_centre + 1.3 * radius).all()
    # most of what shows is the near half
    assert (to_point < to_centre).mean() > 0.7


def test_rendering_is_deterministic_for_a_seed() -> None:
    people = _snap([ALICE, BOB], t=0.7)
    a = _person_renderer(seed=11, noise=True).render(people)
    b = _person_renderer(seed=11, noise=True).render(people)
    c = _person_renderer(seed=12, noise=True).render(people)
    assert np.array_equal(a.frame.depth, b.frame.depth, equal_nan=True)
    assert np.array_equal(a.frame.color, b.frame.color)
    assert np.array_equal(a.frame.intensity, b.frame.intensity)
    assert np.array_equal(a.labels, b.labels)
    assert not np.array_equal(a.frame.depth, c.frame.depth, equal_nan=True)
    assert np.array_equal(a.labels, c.labels)  # the scene is the same, only the noise differs


@pytest.mark.parametrize(
    "lens", [(-0.15, 0.05, 0.0, 0.0, 0.0), (-0.12, 0.04, 0.004, -0.004, 0.02)], ids=str
)
def test_a_lens_renders_what_opencv_remaps_the_pinhole_image_to(lens: tuple) -> None:
    """Rays traced through a distorting lens see what the pinhole image, remapped by
    OpenCV's lens model (an oracle independent of ours), shows at each pixel."""
    cv2 = pytest.importorskip("cv2")
    pinhole = Intrinsics.for_sensor("kinect2")
    people = _snap([ALICE, BOB], t=0.7)
    plain = _person_renderer().render(people).frame
    spec = _spec("kinect2", PERSON_POSE)
    rng = np.random.default_rng(0)
    through = DepthRenderer(
        spec, ROOM, rng, noise=False, intrinsics=pinhole.with_distortion(lens)
    ).render(people)
    grid = np.mgrid[0 : pinhole.height, 0 : pinhole.width][::-1].reshape(2, -1).T
    source = cv2.undistortPoints(
        grid.reshape(-1, 1, 2).astype(np.float64), pinhole.matrix, np.array(lens),
        P=pinhole.matrix,
    ).reshape(pinhole.height, pinhole.width, 2).astype(np.float32)  # fmt: skip
    remapped = cv2.remap(
        plain.depth, source[..., 0], source[..., 1], cv2.INTER_NEAREST,
        borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan,
    )  # fmt: skip
    depth = through.frame.depth
    both = np.isfinite(remapped) & np.isfinite(depth)
    assert both.mean() > 0.8  # a barrel lens sees beyond the pinhole image at its borders
    assert (np.abs(remapped - depth)[both] < 0.03).mean() > 0.98
    assert (through.labels >= 0).sum() > 2000  # the people are drawn
    # ... which is not the pinhole image
    seen = both & np.isfinite(plain.depth)
    assert (np.abs(plain.depth - depth)[seen] > 0.03).mean() > 0.05


KINECT2_LENS = (0.0927, -0.2806, -0.0006, 0.0004, 0.1108)
FACTORY_LENS = (0.0905, -0.2706, 0.0012, -0.0008, 0.0967)


def test_a_simulated_unit_draws_through_its_lens_and_reports_its_factory_one() -> None:
    """``sim_lens``: the renderer traces rays through the unit's own lens, while its
    frames carry the lens its driver reports (or none), as a real unit's do."""
    from openptrack_py.eval.checkerboard import SimSensor

    people = _snap([ALICE, BOB], t=0.7)
    lens = {"distortion": KINECT2_LENS, "reported": FACTORY_LENS}
    cfg = SensorConfig(id="cam", type="kinect2", pose=PERSON_POSE, sim_lens=lens)  # type: ignore[arg-type]
    spec = SensorSpec.from_config(cfg)
    shot = DepthRenderer(spec, ROOM, np.random.default_rng(0), noise=False).render(people)
    pinhole = Intrinsics.for_sensor("kinect2")
    traced = DepthRenderer(
        _spec("kinect2", PERSON_POSE), ROOM, np.random.default_rng(0), noise=False,
        intrinsics=pinhole.with_distortion(KINECT2_LENS),
    ).render(people)  # fmt: skip
    assert np.array_equal(shot.frame.depth, traced.frame.depth, equal_nan=True)
    assert shot.frame.intrinsics == pinhole.with_distortion(FACTORY_LENS)
    assert traced.frame.intrinsics == pinhole.with_distortion(KINECT2_LENS)
    unit = SimSensor.from_config(cfg)
    assert unit.intrinsics == pinhole.with_distortion(KINECT2_LENS)
    assert unit.reports == unit.reported == pinhole.with_distortion(FACTORY_LENS)
    # a driver that does not know its lens: the frames carry the plain pinhole
    unknown = cfg.model_copy(
        update={"sim_lens": cfg.sim_lens.model_copy(update={"reported": None})}
    )  # type: ignore[union-attr]
    shot = DepthRenderer(SensorSpec.from_config(unknown), ROOM, np.random.default_rng(0)).render(
        people
    )
    assert shot.frame.intrinsics == pinhole
    assert SimSensor.from_config(unknown).reports == pinhole
    assert SimSensor.from_config(unknown).reported is None
