"""Furniture at head height is not people: boards, shelves and racks, partly hidden.

A real corridor cloud (five people walking, poster boards and radiators behind them)
gave two false people 4.8 m away: the top edges of boards at head height, seen between
the people in front. The scenes here are rendered the same way: three boards or shelves
4.2-6 m from the sensor with tops at 1.45-1.9 m, five people 2-3.8 m from it.
"""

from __future__ import annotations

import numpy as np
import pytest

from openptrack_py.config import DetectorConfig, Pose, SensorConfig
from openptrack_py.detection.clustering import HeadClusterer
from openptrack_py.detection.pipeline import PeopleDetector
from openptrack_py.geometry import world_from_optical
from openptrack_py.sim.render import DepthRenderer
from openptrack_py.sim.sensors import SensorSpec
from openptrack_py.sim.world import Obstacle, Room
from tests.conftest import people_snapshot
from tests.cores import map_on_cores


def _scene(rng: np.random.Generator) -> tuple[Room, Pose, list] | None:
    """Three boards or shelves behind five people, or None if the people overlap."""
    obstacles = []
    for j in range(3):
        x, y = rng.uniform(4.2, 6.0), rng.uniform(0.3, 2.6)
        w, d = rng.uniform(0.3, 1.2), rng.choice([0.03, rng.uniform(0.2, 0.5)])
        if rng.random() < 0.5:
            w, d = d, w
        top = rng.uniform(1.45, 1.9)
        obstacles.append(Obstacle(f"board_{j}", x, y, x + d, min(y + w, 3.1), top))
    pose = Pose(
        x=0.2, y=1.6, z=rng.uniform(1.8, 2.6), yaw_deg=rng.uniform(-15, 15),
        pitch_deg=rng.uniform(8, 20),
    )  # fmt: skip
    people = [
        (rng.uniform(2.0, 3.8), rng.uniform(0.4, 2.8), rng.uniform(1.55, 1.9),
         rng.uniform(0.19, 0.24), rng.uniform(0, 360), rng.uniform(0, 360))
        for _ in range(5)
    ]  # fmt: skip
    xy = np.array([p[:2] for p in people])
    if (np.linalg.norm(xy[:, None] - xy[None], axis=2) + 9 * np.eye(5)).min() < 0.5:
        return None
    return Room(14.0, 3.2, obstacles=tuple(obstacles)), pose, people


def _count(case: tuple[int, str], trials: int = 40) -> tuple[int, int, int]:
    """False people, people found and people to find over a (seed, sensor type)'s scenes."""
    seed, kind = case
    rng = np.random.default_rng(seed)
    false = found = wanted = 0
    for trial in range(trials):
        scene = _scene(rng)
        if scene is None:
            continue
        room, pose, people = scene
        spec = SensorSpec.from_config(SensorConfig(id="cam", type=kind, pose=pose))  # type: ignore[arg-type]
        renderer = DepthRenderer(spec, room, np.random.default_rng(trial))
        detector = PeopleDetector(
            DetectorConfig(), world_from_camera=world_from_optical(pose), sensor_type=kind,
            rng=np.random.default_rng(0),
        )  # fmt: skip
        snap = people_snapshot(people)
        for k in range(2):
            shot = renderer.render(snap, seq=k)
            result = detector.detect(shot.frame)
        visible = (shot.head_visible >= 0.5 * shot.head_pixels) & (shot.head_pixels > 20)
        wanted += int(visible.sum())
        for d in result.detections:
            gap = np.linalg.norm(snap.pos - d.position[:2], axis=1)
            if gap.min() < 0.3:
                found += int(visible[gap.argmin()])
            else:
                false += 1
    return false, found, wanted


@pytest.mark.slow
def test_board_and_shelf_tops_between_people_are_fewer_people() -> None:
    """Seeds 4-7 (not looked at while developing), Kinect v2 and RealSense.

    The detector before the cap-shape test made 9 + 29 false people here; with it, 7 +
    16; with shoulders asked of every crown-like cap, 5 + 8 (5 + 6 after later changes
    to the renderer); with caps wider across the line of sight than a head taken for
    lines, 5 + 4; and it finds the same people. It does not remove them all:
    a cap right at a shelf's corner, where what lies around it at shoulder reach is the
    floor or the people in front, still passes as a head now and then.
    """
    cases = [(seed, kind) for kind in ("kinect2", "realsense") for seed in range(4, 8)]
    totals = np.array(map_on_cores(_count, cases))
    false, found, wanted = totals.sum(axis=0)
    assert wanted >= 300
    assert found == wanted  # no real person lost
    assert false <= 9, totals


_II, _JJ = np.mgrid[-10:11, -10:11]
_RING2 = _II * _II + _JJ * _JJ  # squared distance from the peak, in cells
_SHOULDERS = (_RING2 >= 2.5**2) & (_RING2 <= 5**2)  # 0.15-0.3 m from the peak


def _crown(around: float) -> np.ndarray:
    """A 0.06 m height map: a crown 0.18 m across at 1.7 m, ``around`` elsewhere."""
    top = np.full((21, 21), around)
    top[_RING2 <= 2] = 1.70
    top[_RING2 == 0] = 1.72
    return top


def test_a_crown_is_a_head_only_with_shoulders_below_it() -> None:
    clusterer = HeadClusterer(cell_m=0.06)
    assert clusterer._is_head(_crown(1.45), 10, 10)  # shoulders 0.27 m lower
    assert clusterer._is_head(_crown(np.nan), 10, 10)  # the body hidden: no say
    # the top edge of a shelf seen between people: a crown-sized cap, and beside it at
    # shoulder reach, a few cells of the same edge at its level, the rest hidden
    edge = _crown(np.nan)
    edge[_SHOULDERS & (_JJ >= 3) & (np.abs(_II) <= 1)] = 1.70
    assert not clusterer._is_head(edge, 10, 10)
    # the ring is judged by its median: a neighbour's shoulder at the peak's level on
    # one side does not turn a head into a board
    top = _crown(1.45)
    top[_SHOULDERS & (_JJ >= 3) & (np.abs(_II) <= 1)] = 1.70
    assert clusterer._is_head(top, 10, 10)


def _cap(cells: list[tuple[int, int]], across: tuple[float, float] | None = None) -> str:
    ci, cj = (np.array(v) for v in zip(*cells, strict=True))
    return HeadClusterer(cell_m=0.06)._cap_shape(
        ci, cj, None if across is None else np.array(across)
    )


def test_cap_shapes_tell_crowns_from_lines_and_flat_tops() -> None:
    disc = [(i, j) for i in range(-2, 3) for j in range(-2, 3) if i * i + j * j <= 4]
    edge = [(0, j) for j in range(-4, 5)] + [(1, j) for j in range(-4, 5)]
    top = [(i, j) for i in range(-5, 6) for j in range(-5, 6)]
    assert _cap(disc) == "crown"  # a head's crown: 0.25 m across
    assert _cap(edge) == "line"  # a board's top edge: 0.54 x 0.12 m
    assert _cap(edge[:5]) == "crown"  # too few cells to call it a line
    assert _cap(top) == "large"  # a shelf's top: 0.66 x 0.66 m
    assert _cap([(0, 0), (0, 1)]) == "crown"


def test_a_cap_wider_across_the_line_of_sight_than_a_head_is_a_line() -> None:
    """A head (at most 0.17 m broad) fills five 0.06 m cells across the line of sight at most.

    Along it, depth noise smears a far head's cap over more cells: that is still a head.
    """
    six = [(0, j) for j in range(6)]  # 0.36 m wide, too few cells for the elongation test
    five = [(0, j) for j in range(5)] + [(1, 2)]
    assert _cap(six, across=(0.0, 1.0)) == "line"  # the sensor looks along i
    assert _cap(six, across=(1.0, 0.0)) == "crown"  # the sensor looks along j
    assert _cap(five, across=(0.0, 1.0)) == "crown"
    assert _cap(six) == "crown"  # the line of sight unknown
    # six cells on a diagonal: one cell wide along the line of sight, 8.1 across it
    oblique = (np.sqrt(0.5), np.sqrt(0.5))
    assert _cap([(k, k) for k in range(6)], across=(-oblique[0], oblique[1])) == "crown"
    assert _cap([(k, k) for k in range(6)], across=oblique) == "line"
