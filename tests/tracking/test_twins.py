"""Twin tracks of sensors whose calibrations disagree, and the rigid map they agree on."""

from __future__ import annotations

import math

import numpy as np
import pytest

from openptrack_py.tracking.alignment import RigidAlignment, rigid_fit, rotation
from openptrack_py.tracking.sensor_model import OnlineSensorModel
from openptrack_py.tracking.state import SENSOR_SLOTS, TrackTable
from openptrack_py.tracking.twins import TwinAligner, TwinLesson


def test_rigid_fit_recovers_a_rotation_and_a_shift() -> None:
    rng = np.random.default_rng(0)
    src = rng.uniform(0, 6, (10, 2))
    dst = src @ rotation(math.radians(4.0)).T + np.array([0.3, -0.2])
    theta, shift = rigid_fit(src, dst)
    assert math.degrees(theta) == pytest.approx(4.0)
    assert np.allclose(shift, [0.3, -0.2])


SEEN_B = (math.radians(3.0), np.array([0.45, -0.6]))
"""Where sensor 1 puts everybody, against sensor 0: 3 degrees and 0.75 m off."""


def _walkers(t: float, n: int) -> np.ndarray:
    """``n`` people walking their own straight lines across a room (true positions)."""
    k = np.arange(n)
    start = np.column_stack([1.0 + 1.5 * k, 1.0 + 0.8 * k])
    heading = 0.7 + 1.3 * k
    return start + 0.8 * t * np.column_stack([np.cos(heading), np.sin(heading)])


def _table(a: np.ndarray, b: np.ndarray, t: float) -> TrackTable:
    """Tracks ``a`` fed by sensor 0 alone, tracks ``b`` by sensor 1 alone."""
    n = len(a) + len(b)
    table = TrackTable()
    table.ids = np.arange(1, n + 1)
    table.x = np.column_stack([np.vstack([a, b]), np.zeros((n, 2))])
    table.confirmed = np.ones(n, dtype=bool)
    table.first_seen = np.full(n, -10.0)
    table.last_seen = np.full(n, t)
    table.sensor_hit_t = np.full((n, SENSOR_SLOTS), -np.inf)
    table.sensor_hit_t[: len(a), 0] = t
    table.sensor_hit_t[len(a) :, 1] = t
    return table


def _run(
    aligner: TwinAligner,
    twins: int,
    offsets: np.ndarray | None = None,
    unshared: frozenset[int] = frozenset({0, 1}),
) -> list[TwinLesson]:
    """Every person seen by sensor 0 and, through its calibration, by sensor 1."""
    lessons = []
    for step in range(40):  # 10 s, a look every 0.25 s
        t = 0.25 * step
        truth = _walkers(t, twins)
        seen_b = truth @ rotation(SEEN_B[0]).T + SEEN_B[1] if offsets is None else truth + offsets
        lessons += aligner.observe(_table(truth, seen_b, t), t, set(unshared))
    return lessons


def test_three_people_agreeing_on_one_map_teach_it() -> None:
    lessons = _run(TwinAligner(), twins=3)
    assert lessons, "no lesson"
    first = lessons[0]
    assert first.sensors_a == (0,) and first.sensor_b == 1
    theta, shift = rigid_fit(first.b, first.a)  # sensor 1 onto sensor 0
    assert abs(math.degrees(theta) + 3.0) < 0.2
    back = first.b @ rotation(theta).T + shift
    assert np.abs(back - first.a).max() < 0.02


def test_one_pair_walking_together_teaches_nothing() -> None:
    assert _run(TwinAligner(), twins=1) == []


def test_people_walking_together_at_offsets_no_rigid_map_explains_teach_nothing() -> None:
    # three couples, each walking side by side 0.6-0.7 m apart in its own direction
    offsets = np.array([[0.0, 0.7], [0.6, 0.0], [-0.45, -0.45]])
    assert _run(TwinAligner(), twins=3, offsets=offsets) == []


def test_a_sensor_whose_tracks_others_feed_is_not_taught() -> None:
    # its share is high: it is calibrated, and its twins must be people walking together
    assert _run(TwinAligner(), twins=3, unshared=frozenset({0})) == []
    assert _run(TwinAligner(), twins=3, unshared=frozenset({1})) == []


def test_a_copy_keeps_its_own_samples() -> None:
    aligner = TwinAligner()
    _run(aligner, twins=1)
    copy = aligner.copy()
    assert len(copy.rows) and np.array_equal(copy.rows, aligner.rows)
    aligner.rows[:] = 0
    assert copy.rows.any()


def test_an_alignment_followed_by_a_move_keeps_its_pairs() -> None:
    rng = np.random.default_rng(1)
    align = RigidAlignment()
    z = rng.uniform(0, 6, (50, 2))
    align.add(z, z + np.array([0.1, 0.0]))
    align.fit()
    align.then(math.radians(2.0), np.array([0.0, 0.2]))
    moved = align.apply(z)
    expected = (z + np.array([0.1, 0.0])) @ rotation(math.radians(2.0)).T + np.array([0.0, 0.2])
    assert np.allclose(moved, expected)
    align.fit()  # the remembered targets moved with it: the fit agrees
    assert np.allclose(align.apply(z), expected)
    assert align.weight == 50


def test_a_sensor_model_snapshot_keeps_the_twins_and_an_older_one_restores() -> None:
    model = OnlineSensorModel(twins=TwinAligner())
    assert model.twins is not None
    model.twins.rows = np.ones((3, 9))
    state = model.snapshot()
    model.twins.rows = np.zeros((0, 9))
    model.restore(state)
    assert len(model.twins.rows) == 3
    model.restore(state[:2])  # a checkpoint from before twins were kept: they stay
    assert len(model.twins.rows) == 3
