"""The scripted checkerboard session: where the board is held, and who holds it.

Multi-sensor calibration in OpenPTrack (Munaro et al., OpenPTrack, §4) has someone walk
through the room holding a checkerboard so that pairs of sensors see it at once, then
lay it flat on the floor to fix the world frame. This module plans that session for the
simulator (the board is drawn into rendered frames by :mod:`openptrack_py.sim.boards`):

* :func:`board_session` — board placements held by someone walking around (tilted at
  varying angles, centres 0.8-1.8 m above the floor), each chosen to be seen by a pair
  of sensors (every pair whose views overlap, in turn) and often by more; then one
  placement laid flat on the floor where the sensors see it best;
* :func:`board_visible` — whether a camera would see the whole board well enough to find
  its corners (what the person holding it checks on the calibration screen);
* :func:`holder_snapshot` — the world during a placement: the person holding the board.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from openptrack_py.calibration.checkerboard import Checkerboard
from openptrack_py.detection.frame import Intrinsics
from openptrack_py.detection.lens import unfolded
from openptrack_py.geometry import invert, polygon_area, world_from_optical
from openptrack_py.sensor_types import SENSOR_TYPES
from openptrack_py.sim.boards import BOARD_THICKNESS_M
from openptrack_py.sim.sensor_spec import SensorSpec
from openptrack_py.sim.world import Room, Snapshot

__all__ = [
    "MIN_SQUARE_PX",
    "BoardPlacement",
    "BoardSession",
    "board_session",
    "board_visible",
    "holder_snapshot",
]


@dataclass(frozen=True, eq=False)
class BoardPlacement:
    """One placement of the board, held still while the sensors capture it.

    Parameters
    ----------
    stamp : float
        When the board is still at this pose, seconds from the session's start.
    world_from_board : ndarray
        4x4 pose of the board frame in the world.
    on_floor : bool
        The board lies flat on the floor, printed side up (the world-frame placement).
    holder_xy : tuple of float, optional
        Where the person holding the board stands; None when nobody holds it.
    """

    stamp: float
    world_from_board: np.ndarray
    on_floor: bool = False
    holder_xy: tuple[float, float] | None = None


@dataclass(frozen=True, eq=False)
class BoardSession:
    """A scripted calibration session: the board's placements in time order.

    Parameters
    ----------
    board : Checkerboard
        The board moved around.
    placements : tuple of BoardPlacement
        Held placements, then the one on the floor.
    """

    board: Checkerboard
    placements: tuple[BoardPlacement, ...]

    @property
    def floor(self) -> BoardPlacement | None:
        """The placement on the floor, if the session has one."""
        return next((p for p in self.placements if p.on_floor), None)


MIN_SQUARE_PX = 5.5
"""Smallest square, in pixels, at which a session counts on the board being found."""


@dataclass(frozen=True, eq=False)
class _Camera:
    """A sensor as the session planner sees it."""

    world_from_camera: np.ndarray
    camera_from_world: np.ndarray
    intrinsics: Intrinsics
    sensor_type: str

    @classmethod
    def of(cls, spec: SensorSpec) -> _Camera:
        pose = world_from_optical(spec.pose)
        return cls(pose, invert(pose), Intrinsics.for_sensor(spec.type.name), spec.type.name)

    def reach_m(self, board: Checkerboard, min_square_px: float) -> float:
        """Farthest depth at which a board facing the camera has big enough squares."""
        k = self.intrinsics
        far = min(k.fx, k.fy) * board.square_m / min_square_px
        return min(far, SENSOR_TYPES[self.sensor_type].max_range_m)


def _visible(
    board: Checkerboard,
    camera_from_board: np.ndarray,
    k: Intrinsics,
    sensor_type: str,
    max_angle_deg: float,
    min_square_px: float,
    margin_px: float,
) -> bool:
    """:func:`board_visible` of a board pose already in the camera frame."""
    rot, origin = camera_from_board[:3, :3], camera_from_board[:3, 3]
    if float(origin @ rot[:, 2]) <= 0:  # the camera is behind the board
        return False
    kind = SENSOR_TYPES[sensor_type]
    outline = board.outline() @ rot.T + origin
    z = outline[:, 2]
    if z.min() < kind.min_range_m or z.max() > kind.max_range_m:
        return False
    if k.has_lens and not unfolded(outline[:, 0] / z, outline[:, 1] / z, k.distortion).all():
        return False  # partly beyond the lens's fold: part of it is out of the image
    u, v = k.pixels(outline)
    if u.min() < margin_px or v.min() < margin_px:
        return False
    if u.max() > k.width - 1 - margin_px or v.max() > k.height - 1 - margin_px:
        return False
    centre = board.centre @ rot.T + origin
    cos = abs(float(rot[:, 2] @ centre)) / float(np.linalg.norm(centre))
    if cos < math.cos(math.radians(max_angle_deg)):
        return False
    pts = board.object_points() @ rot.T + origin
    px = np.column_stack([k.fx * pts[:, 0] / pts[:, 2], k.fy * pts[:, 1] / pts[:, 2]])
    grid = px.reshape(board.rows, board.cols, 2)
    along = np.linalg.norm(np.diff(grid, axis=1), axis=-1).min()
    down = np.linalg.norm(np.diff(grid, axis=0), axis=-1).min()
    return bool(min(along, down) >= min_square_px)


def board_visible(
    board: Checkerboard,
    world_from_board: np.ndarray,
    world_from_camera: np.ndarray,
    intrinsics: Intrinsics,
    sensor_type: str,
    *,
    max_angle_deg: float = 60.0,
    min_square_px: float = MIN_SQUARE_PX,
    margin_px: float = 3.0,
) -> bool:
    """Whether a camera would see the whole board well enough to find its corners.

    What the person holding the board checks on the calibration screen: the printed side
    faces the camera, the whole board is in the image (``margin_px`` inside its edges),
    within the sensor's depth range, not seen more obliquely than ``max_angle_deg`` and
    with squares of at least ``min_square_px`` pixels. Occlusion is not tested.
    """
    camera_from_board = invert(world_from_camera) @ world_from_board
    return _visible(
        board, camera_from_board, intrinsics, sensor_type, max_angle_deg, min_square_px, margin_px
    )


def _seen_by(
    board: Checkerboard,
    pose: np.ndarray,
    cameras: Sequence[_Camera],
    max_angle_deg: float = 60.0,
) -> list[int]:
    """Indices of the cameras that would see the board at ``pose``."""
    return [
        i
        for i, c in enumerate(cameras)
        if _visible(board, c.camera_from_world @ pose, c.intrinsics, c.sensor_type,
                    max_angle_deg, MIN_SQUARE_PX, 3.0)
    ]  # fmt: skip


def _facing_pose(
    board: Checkerboard, centre: np.ndarray, facing: np.ndarray, spin: float
) -> np.ndarray:
    """``world_from_board`` of a board centred at ``centre`` whose print faces ``facing``.

    The board's x axis is horizontal before the in-plane rotation ``spin`` (radians).
    """
    z = -facing / np.linalg.norm(facing)  # board z points away from the viewers
    right = np.cross(z, [0.0, 0.0, 1.0])
    if np.linalg.norm(right) < 1e-6:  # facing straight up or down
        right = np.array([1.0, 0.0, 0.0])
    right /= np.linalg.norm(right)
    down = np.cross(z, right)
    c, s = math.cos(spin), math.sin(spin)
    x, y = c * right + s * down, -s * right + c * down
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([x, y, z])
    pose[:3, 3] = centre - pose[:3, :3] @ board.centre
    return pose


def _tilted(direction: np.ndarray, max_deg: float, rng: np.random.Generator) -> np.ndarray:
    """``direction`` turned by up to ``max_deg`` about a random perpendicular axis."""
    d = direction / np.linalg.norm(direction)
    axis = np.cross(d, rng.standard_normal(3))
    axis /= np.linalg.norm(axis)
    angle = math.radians(rng.uniform(0.0, max_deg))
    # Rodrigues' rotation of d about an axis perpendicular to it.
    return d * math.cos(angle) + np.cross(axis, d) * math.sin(angle)


def _holder_at(room: Room, world_from_board: np.ndarray, distance_m: float) -> np.ndarray | None:
    """Where someone holding the board stands: behind it; None if that is not free floor."""
    back = world_from_board[:3, 2][:2]
    if np.linalg.norm(back) < 0.2:
        return None
    centre = world_from_board[:3, 3][:2]
    xy = centre + distance_m * back / np.linalg.norm(back)
    return xy if room.free(xy, margin=0.25)[0] else None


def _point_in_view(
    camera: _Camera, near_m: float, far_m: float, rng: np.random.Generator
) -> np.ndarray:
    """A random world point in the middle of a camera's image, ``near_m``-``far_m`` deep."""
    k = camera.intrinsics
    u = rng.uniform(0.2, 0.8) * (k.width - 1)
    v = rng.uniform(0.2, 0.8) * (k.height - 1)
    z = rng.uniform(near_m, max(far_m, near_m))
    cam = np.array([(u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z])
    return camera.world_from_camera[:3, :3] @ cam + camera.world_from_camera[:3, 3]


def _held_placement(
    board: Checkerboard,
    room: Room,
    cameras: Sequence[_Camera],
    pair: tuple[int, int],
    rng: np.random.Generator,
    *,
    tries: int,
    max_tilt_deg: float,
) -> tuple[np.ndarray, np.ndarray] | None:
    """A held board pose seen by both sensors of ``pair``: ``(world_from_board, holder_xy)``.

    Centres are drawn in the view of the pair's sensor of shorter reach (where the
    person holding the board would walk to); of a few poses both sensors see, the one
    the most sensors see is kept.
    """
    reach = [cameras[i].reach_m(board, MIN_SQUARE_PX) for i in pair]
    anchor = cameras[pair[int(np.argmin(reach))]]
    far = min(reach) * 0.95
    centres = [cameras[i].world_from_camera[:3, 3] for i in pair]
    best: tuple[int, np.ndarray, np.ndarray] | None = None
    accepted = 0
    for _ in range(tries):
        centre = _point_in_view(anchor, 1.0, far, rng)
        if not (0.8 <= centre[2] <= 1.8 and room.free(centre[:2], margin=0.3)[0]):
            continue
        bisector = sum((c - centre) / np.linalg.norm(c - centre) for c in centres)
        facing = _tilted(bisector, max_tilt_deg, rng)
        pose = _facing_pose(board, centre, facing, math.radians(rng.uniform(-30.0, 30.0)))
        holder = _holder_at(room, pose, 0.45)
        if holder is None:
            continue
        seen = _seen_by(board, pose, cameras)
        if pair[0] not in seen or pair[1] not in seen:
            continue
        accepted += 1
        if best is None or len(seen) > best[0]:
            best = (len(seen), pose, holder)
        if accepted >= 4:
            break
    return None if best is None else (best[1], best[2])


def _grid_area_px(board: Checkerboard, camera: _Camera, world_from_board: np.ndarray) -> float:
    """Image area covered by the board's inner corners, square pixels."""
    obj = board.object_points()
    ends = obj[[0, board.cols - 1, -1, -board.cols]]
    pose = camera.camera_from_world @ world_from_board
    cam = ends @ pose[:3, :3].T + pose[:3, 3]
    k = camera.intrinsics
    return polygon_area(np.column_stack([k.fx * cam[:, 0], k.fy * cam[:, 1]]) / cam[:, 2:3])


def _floor_placement(
    board: Checkerboard,
    room: Room,
    cameras: Sequence[_Camera],
    rng: np.random.Generator,
    tries: int,
) -> np.ndarray:
    """The board flat on the floor where it is seen best: the most image area in all views.

    The floor board fixes the world frame for every sensor, so it goes where the
    sensors that see it see it large (near, not too oblique), rather than merely where
    the most sensors see it.
    """
    best: tuple[float, np.ndarray] | None = None
    for _ in range(tries):
        xy = rng.uniform((0.8, 0.8), (room.width - 0.8, room.depth - 0.8))
        if not room.free(xy, margin=0.7)[0]:
            continue
        centre = np.array([xy[0], xy[1], BOARD_THICKNESS_M])
        pose = _facing_pose(board, centre, np.array([0.0, 0.0, 1.0]), 0.0)
        yaw = rng.uniform(-math.pi, math.pi)
        turn = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
        pose[:2, :3] = turn @ pose[:2, :3]
        pose[:3, 3] = centre - pose[:3, :3] @ board.centre
        score = sum(_grid_area_px(board, cameras[i], pose) for i in _seen_by(board, pose, cameras))
        if best is None or score > best[0]:
            best = (score, pose)
    if best is None:
        raise ValueError("board session: the room has no free floor for the board")
    return best[1]


def board_session(
    board: Checkerboard,
    room: Room,
    sensors: Sequence[SensorSpec],
    rng: np.random.Generator,
    *,
    placements: int = 30,
    dwell_s: float = 3.0,
    max_tilt_deg: float = 30.0,
    floor: bool = True,
    tries: int = 400,
) -> BoardSession:
    """Script a calibration session: held placements seen by pairs, then the floor.

    The held placements go round every pair of sensors in turn (the pairs whose views
    overlap: a pair for which no pose is found in ``tries`` draws is dropped). Each is a
    board centred 0.8-1.8 m above free floor, in the view of the pair's sensor of shorter
    reach (where its squares are at least :data:`MIN_SQUARE_PX` pixels), facing between
    the two sensors, then tilted by up to ``max_tilt_deg`` and turned in its plane by up
    to 30 degrees; of a few such poses the one seen by the most sensors is kept. The
    person holding the board stands 0.45 m behind it.

    Parameters
    ----------
    board : Checkerboard
        The board.
    room : Room
        The room (the board and its holder stay on free floor).
    sensors : sequence of SensorSpec
        The sensors, with their true poses.
    rng : numpy.random.Generator
        Source of the script's randomness.
    placements : int
        Held placements.
    dwell_s : float
        Time between placements, seconds.
    max_tilt_deg : float
        Largest tilt of the board away from facing the pair.
    floor : bool
        End with the board flat on the floor where the sensors see it best.
    tries : int
        Random poses tried per placement.

    Returns
    -------
    BoardSession
        Fewer held placements than asked when no pair of sensors shares a view.
    """
    cameras = [_Camera.of(s) for s in sensors]
    pairs = list(combinations(range(len(sensors)), 2))
    out: list[BoardPlacement] = []
    turn = 0
    while len(out) < placements and pairs:
        pair = pairs[turn % len(pairs)]
        found = _held_placement(
            board, room, cameras, pair, rng, tries=tries, max_tilt_deg=max_tilt_deg
        )
        if found is None:
            pairs.remove(pair)
            continue
        turn += 1
        pose, holder = found
        stamp = dwell_s * (len(out) + 1)
        out.append(BoardPlacement(stamp, pose, False, (float(holder[0]), float(holder[1]))))
    if floor and sensors:
        pose = _floor_placement(board, room, cameras, rng, tries)
        out.append(BoardPlacement(dwell_s * (len(out) + 1), pose, True, None))
    return BoardSession(board, tuple(out))


def holder_snapshot(placement: BoardPlacement, stamp: float) -> Snapshot:
    """The world as the sensors see it during a placement: its holder, or nobody."""
    n = 0 if placement.holder_xy is None else 1
    pos = np.array([placement.holder_xy]) if n else np.zeros((0, 2))
    return Snapshot(
        t=stamp,
        ids=np.arange(1, n + 1),
        kinds=np.array(["adult"] * n, dtype="<U5"),
        pos=pos,
        vel=np.zeros((n, 2)),
        height=np.full(n, 1.75),
        radius=np.full(n, 0.21),
        top_hue=np.full(n, 210.0),
        bottom_hue=np.full(n, 30.0),
    )
