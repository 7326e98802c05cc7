"""Two people within one detection's reach: tracks on a collision course slow down."""

from __future__ import annotations

import math

import numpy as np
import pytest

from openptrack_py.tracking.blobs import slow_approaches
from openptrack_py.tracking.state import TrackTable


def _table(states: list[tuple[float, float, float, float]], confirmed: list[bool]) -> TrackTable:
    n = len(states)
    tb = TrackTable()
    tb.x = np.array(states, dtype=float)
    tb.ids = np.arange(1, n + 1)
    tb.confirmed = np.array(confirmed)
    return tb


BOTH = np.array([[True], [True]])  # one detection, in both tracks' gates


def test_the_approach_speed_decays_with_its_time_constant_and_the_mean_velocity_is_kept() -> None:
    tb = _table([(0.0, 0.0, 1.0, 0.2), (0.4, 0.0, -1.0, -0.3)], [True, True])
    before = tb.x.copy()
    slow_approaches(tb, BOTH, dt=0.1, stop_s=0.3)
    closing_before = before[0, 2] - before[1, 2]
    closing_after = tb.x[0, 2] - tb.x[1, 2]
    assert closing_after == pytest.approx(closing_before * math.exp(-0.1 / 0.3))
    # sideways motion (across the line between them) and the pair's mean velocity stay
    np.testing.assert_allclose(tb.x[:, 3], before[:, 3])
    np.testing.assert_allclose(tb.x[:, 2:4].mean(axis=0), before[:, 2:4].mean(axis=0))
    np.testing.assert_array_equal(tb.x[:, 0:2], before[:, 0:2])


@pytest.mark.parametrize(
    ("states", "gated", "confirmed", "stop_s"),
    [
        # side by side, walking together
        ([(0.0, 0.0, 1.0, 0.0), (0.0, 0.4, 1.0, 0.0)], BOTH, [True, True], 0.3),
        # passing each other a body apart (closest approach 0.4 m)
        ([(0.0, 0.0, 1.0, 0.0), (0.5, 0.4, -1.0, 0.0)], BOTH, [True, True], 0.3),
        # moving apart
        ([(0.0, 0.0, -1.0, 0.0), (0.4, 0.0, 1.0, 0.0)], BOTH, [True, True], 0.3),
        # approaching, but each in its own detection's gate only
        ([(0.0, 0.0, 1.0, 0.0), (0.4, 0.0, -1.0, 0.0)], np.eye(2, dtype=bool), [True, True], 0.3),
        # approaching a tentative track
        ([(0.0, 0.0, 1.0, 0.0), (0.4, 0.0, -1.0, 0.0)], BOTH, [True, False], 0.3),
        # the rule off
        ([(0.0, 0.0, 1.0, 0.0), (0.4, 0.0, -1.0, 0.0)], BOTH, [True, True], 0.0),
    ],
    ids=["side-by-side", "passing", "parting", "two-detections", "tentative", "off"],
)
def test_nothing_else_slows_down(
    states: list[tuple[float, float, float, float]],
    gated: np.ndarray,
    confirmed: list[bool],
    stop_s: float,
) -> None:
    tb = _table(states, confirmed)
    before = tb.x.copy()
    slow_approaches(tb, gated, dt=0.1, stop_s=stop_s)
    np.testing.assert_array_equal(tb.x, before)


def test_three_tracks_in_one_blob_stop_closing_in_pairwise() -> None:
    tb = _table([(0.0, 0.0, 1.0, 0.0), (0.5, 0.0, -1.0, 0.0), (0.25, 0.4, 0.0, -1.0)], [True] * 3)
    gated = np.ones((3, 1), dtype=bool)
    momentum = tb.x[:, 2:4].sum(axis=0)
    for _ in range(100):
        slow_approaches(tb, gated, dt=1 / 30, stop_s=0.3)
    # all heading for one spot: in the end no two of them close in on each other
    for a, b in ((0, 1), (0, 2), (1, 2)):
        u = tb.x[b, 0:2] - tb.x[a, 0:2]
        assert (tb.x[a, 2:4] - tb.x[b, 2:4]) @ u / np.linalg.norm(u) < 1e-3
    np.testing.assert_allclose(tb.x[:, 2:4].sum(axis=0), momentum, atol=1e-12)
