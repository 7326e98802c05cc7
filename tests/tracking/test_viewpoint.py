"""Where the sensors stand, learned from detection ranges, and who hides whom."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from openptrack_py.config import TrackerConfig
from openptrack_py.messages.detection import Detection, DetectionBatch
from openptrack_py.tracking import build_tracker
from openptrack_py.tracking.bookkeeping import update_support
from openptrack_py.tracking.coverage import Coverage
from openptrack_py.tracking.params import TrackerParams
from openptrack_py.tracking.state import SENSOR_SLOTS, TrackTable
from openptrack_py.tracking.viewpoint import MIN_DETECTIONS, Viewpoints, hidden
from tests.tracking.helpers import FRAME, T0

SENSOR = np.array([3.0, 0.3])
HEIGHT = 2.0  # sensor above the people's centroids
LOW = 0.6  # a sensor on a tripod at head height


def _ranges(
    xy: np.ndarray, rng: np.random.Generator, sigma: float = 0.02, height: float = HEIGHT
) -> np.ndarray:
    d = np.sqrt(np.sum((xy - SENSOR) ** 2, axis=1) + height**2)
    return d + rng.normal(0.0, sigma, len(d))


def test_a_sensor_is_located_from_the_ranges_of_its_detections() -> None:
    rng = np.random.default_rng(1)
    views = Viewpoints()
    xy = rng.uniform([0.0, 2.0], [8.0, 9.0], (200, 2))
    views.add("s", xy[: MIN_DETECTIONS - 1], _ranges(xy[: MIN_DETECTIONS - 1], rng))
    assert views.view("s") is None  # too few yet
    views.add("s", xy, _ranges(xy, rng))
    view = views.view("s")
    assert view is not None
    assert np.hypot(*(view[0] - SENSOR)) < 0.1
    assert abs(view[1] - HEIGHT) < 0.1
    assert views.view("other") is None


def test_detections_along_one_line_do_not_locate_a_sensor() -> None:
    rng = np.random.default_rng(2)
    views = Viewpoints()
    xy = np.column_stack([rng.uniform(0.0, 8.0, 100), np.full(100, 4.0)])
    views.add("s", xy, _ranges(xy, rng))
    assert views.view("s") is None


def test_a_replayed_batch_locates_nothing_twice() -> None:
    rng = np.random.default_rng(3)
    cov = Coverage()
    xy = rng.uniform([0.0, 2.0], [8.0, 9.0], (40, 2))
    cov.mark("s", 7, xy, _ranges(xy, rng))
    first = cov._viewpoints._sensors["s"].n
    cov.mark("s", 7, xy, _ranges(xy, rng))
    assert cov._viewpoints._sensors["s"].n == first == 40


@pytest.mark.parametrize(
    ("target", "expected"),
    [
        ((3.0, 6.0), True),  # straight behind the seen person at (3, 3)
        ((3.25, 6.0), True),  # a little off the line of sight, still behind
        ((3.8, 6.0), False),  # beside the line of sight
        ((3.0, 2.0), False),  # in front of them
        ((3.0, 3.5), False),  # within their twin distance: maybe their second track
    ],
)
def test_a_position_is_hidden_only_behind_a_seen_person(
    target: tuple[float, float], expected: bool
) -> None:
    xy = np.array([[3.0, 3.0], target])
    assert hidden(SENSOR, xy, np.array([0]), twin_m=0.9).tolist() == [False, expected]


@pytest.mark.parametrize(
    ("height", "expected"),
    [
        (0.5, True),  # a sensor at head height: anyone in between blocks
        (1.0, True),  # 1 m above the centroids: the line of sight meets the head
        (2.0, False),  # on a 3 m ceiling: it looks over the person 3 m in front
        (6.0, False),
    ],
)
def test_a_high_sensor_looks_over_the_people_in_between(height: float, expected: bool) -> None:
    # seen person 2.7 m from the sensor, the other 3 m behind them
    xy = np.array([[3.0, 3.0], [3.0, 6.0]])
    assert hidden(SENSOR, xy, np.array([0]), 0.9, height).tolist() == [False, expected]


def test_whether_a_position_is_hidden_does_not_depend_on_its_being_seen() -> None:
    xy = np.array([[3.0, 3.0], [3.0, 6.0]])
    assert hidden(SENSOR, xy, np.array([0]), twin_m=0.9).tolist() == [False, True]
    assert hidden(SENSOR, xy, np.array([0, 1]), twin_m=0.9).tolist() == [False, True]
    assert not hidden(SENSOR, xy, np.array([], dtype=int), twin_m=0.9).any()


def test_a_hidden_track_neither_gains_nor_loses_support_or_evidence() -> None:
    """Hidden frames count for nothing, detected or not: a static false positive behind
    people would otherwise have its misses excused and its hits counted."""
    tb = TrackTable(
        ids=np.arange(4),
        x=np.zeros((4, 4)),
        support=np.full(4, 0.8),
        evidence=np.zeros(4),
        sensor_hit_t=np.full((4, SENSOR_SLOTS), T0),
    )
    params = TrackerParams(support_rate=0.5, evidence_per_hit=1.0, evidence_per_miss=-2.0)
    expected = np.ones(4, dtype=bool)
    hid = np.array([False, True, False, True])
    update_support(tb, np.array([0, 3]), expected, 0, T0 + 0.1, params, hid)
    assert tb.support[1] == tb.support[3] == 0.8  # hidden: missed or detected, nothing said
    assert tb.evidence[1] == tb.evidence[3] == 0.0
    assert tb.support[2] < 0.8 and tb.evidence[2] < 0.0  # visible and missed
    assert tb.support[0] > 0.8 and tb.evidence[0] > 0.0  # visible and detected


def _stream(hide_b: bool, still_s: float = 3.0, hidden_s: float = 6.0) -> list[set[int]]:
    """Four people seen by one sensor at head height; B walks in behind A, stays hidden,
    then is seen again.

    While hidden, B is glimpsed in one frame of ten. Returns the ids of the tracks near
    B in each frame after B reappears.
    """
    people = {"A": (3.0, 3.0), "B": (3.0, 6.0), "C": (0.5, 4.5), "D": (6.0, 5.0)}
    config = TrackerConfig(occlusion_aware_support=hide_b)
    tracker = build_tracker(config)
    rng = np.random.default_rng(4)
    ids_near_b: list[set[int]] = []
    total = still_s + hidden_s + 2.0
    for k in range(int(total / FRAME)):
        t = k * FRAME
        dets = []
        for name, (x, y) in people.items():
            if name == "B" and t < still_s:  # B walks in from the side, then stands
                x += 2.0 * (1.0 - t / still_s)
            blocked = name == "B" and still_s <= t < still_s + hidden_s and k % 10 != 0
            if blocked:
                continue
            xy = np.array([x, y]) + rng.normal(0.0, 0.03, 2)
            rng_m = float(np.sqrt(np.sum((xy - SENSOR) ** 2) + LOW**2))
            dets.append(Detection(x=xy[0], y=xy[1], z=1.0, height=1.7, confidence=0.9,
                                  distance=rng_m))  # fmt: skip
        out = tracker.step(DetectionBatch("s", k, T0 + t, "world", tuple(dets)))
        if t >= still_s + hidden_s + 1.0:
            near = {tr.id for tr in out.tracks if np.hypot(tr.x - 3.0, tr.y - 6.0) < 0.5}
            ids_near_b.append(near)
    return ids_near_b


def test_a_person_hidden_behind_another_keeps_their_track() -> None:
    before = _stream(hide_b=True, hidden_s=0.0)  # never hidden: B's id from the start
    after = _stream(hide_b=True)
    assert all(len(ids) == 1 for ids in after)
    assert set().union(*after) == set().union(*before)


def test_without_occlusion_reasoning_the_hidden_person_loses_their_track() -> None:
    """The oracle's counterpart: the same stream loses B when every covered miss counts."""
    before = _stream(hide_b=False, hidden_s=0.0)
    after = _stream(hide_b=False)
    assert set().union(*after) != set().union(*before)


def test_a_coverage_pickled_before_viewpoints_existed_learns_them_afresh() -> None:
    rng = np.random.default_rng(6)
    old = Coverage()
    del old._viewpoints  # what a checkpoint of an earlier version holds
    cov = pickle.loads(pickle.dumps(old))
    xy = rng.uniform([0.0, 2.0], [8.0, 9.0], (60, 2))
    assert not cov.hidden("s", xy, np.array([0]), 0.9).any()
    cov.mark("s", 1, xy, _ranges(xy, rng))
    assert cov._viewpoints.view("s") is not None


def test_covered_by_any_of_several_sensors_is_covered_by_one_of_them() -> None:
    rng = np.random.default_rng(5)
    cov = Coverage()
    for k, name in enumerate(("a", "b", "c")):
        xy = rng.uniform([3.0 * k, 0.0], [3.0 * k + 4.0, 4.0], (400, 2))
        cov.mark(name, 0, xy)
    probe = rng.uniform([-1.0, -1.0], [11.0, 5.0], (300, 2))
    for names in (["a"], ["a", "c"], ["b", "c", "unknown"], []):
        one_by_one = np.zeros(len(probe), dtype=bool)
        for name in names:
            one_by_one |= cov.covers(name, probe)
        assert np.array_equal(cov.covers_any(names, probe), one_by_one)
    assert cov.covers_any(["a", "b"], probe).any()
    assert not cov.covers_any(["a", "b"], probe).all()
