"""Two people within one detection's reach: tracks on a collision course slow down, and two
people's tracks are never estimated closer than a body's depth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from openptrack_py.config import TrackerConfig
from openptrack_py.tracking import build_tracker
from openptrack_py.tracking.blobs import (
    BLOB_RADIUS_M,
    keep_apart,
    shared_noise,
    slow_approaches,
)
from openptrack_py.tracking.state import TrackTable
from tests.tracking.helpers import FRAME, T0, det, make_batch


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


def _with_cov(tb: TrackTable, variances: list[float]) -> TrackTable:
    """Position variances ``variances``, velocity 1 and position-velocity 0.5 times them."""
    cov = np.zeros((len(variances), 4, 4))
    for k, v in enumerate(variances):
        cov[k] = v * np.array([[1, 0, 0.5, 0], [0, 1, 0, 0.5], [0.5, 0, 1, 0], [0, 0.5, 0, 1]])
    tb.cov = cov
    return tb


def test_two_peoples_estimates_are_pushed_a_body_apart_by_their_share_of_uncertainty() -> None:
    tb = _with_cov(_table([(0.0, 0.0, 1.0, 0.0), (0.05, 0.0, 0.0, 0.0)], [True] * 2), [0.03, 0.01])
    before = tb.x.copy()
    keep_apart(tb, np.array([0]), np.array([1]), 0.2)
    assert tb.x[1, 0] - tb.x[0, 0] == pytest.approx(0.2)  # apart, in the same order
    # the more uncertain track moves three times as far; velocities move with positions
    moved = tb.x - before
    assert moved[0, 0] == pytest.approx(-3 * moved[1, 0])
    assert moved[0, 2] == pytest.approx(0.5 * moved[0, 0])
    assert moved[1, 2] == pytest.approx(0.5 * moved[1, 0])
    np.testing.assert_array_equal(moved[:, [1, 3]], 0.0)  # nothing across the line


@pytest.mark.parametrize(
    ("states", "gap"),
    [
        ([(0.0, 0.0, 0.0, 0.0), (0.0, 0.25, 0.0, 0.0)], 0.2),  # already a body apart
        ([(0.0, 0.0, 0.0, 0.0), (0.0, 0.05, 0.0, 0.0)], 0.0),  # the rule off
        ([(0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0)], 0.2),  # one spot: no side to push to
    ],
    ids=["apart", "off", "coincident"],
)
def test_nothing_else_is_pushed(
    states: list[tuple[float, float, float, float]], gap: float
) -> None:
    tb = _with_cov(_table(states, [True, True]), [0.01, 0.01])
    before = tb.x.copy()
    keep_apart(tb, np.array([0]), np.array([1]), gap)
    np.testing.assert_array_equal(tb.x, before)


def _meet_and_part(s: float) -> tuple[float, float]:
    """Where A and B are ``s`` seconds in: they walk up to each other at 1 m/s each, stand
    0.3 m apart for a second, and walk back the way they came."""
    walked = max(min(s, 2.35) - max(s - 3.35, 0.0), 0.0)
    return -2.5 + walked, 2.5 - walked


@pytest.mark.parametrize(("gap", "kept"), [(0.2, True), (0.0, False)], ids=["on", "off"])
def test_two_people_who_meet_in_one_blob_part_with_their_own_ids(gap: float, kept: bool) -> None:
    # Closer than 0.45 m they come out as one blob at their midpoint. The blob is one
    # track's detection; the other track coasts on through it unless the two are kept a
    # body apart, and when they part each track takes the other person.
    tracker = build_tracker(TrackerConfig(person_gap_m=gap))
    owners = []
    for k in range(int(5.5 / FRAME)):
        a, b = _meet_and_part(k * FRAME)
        dets = [det((a + b) / 2, 0.0)] if b - a < 0.45 else [det(a, 0.0), det(b, 0.0)]
        out = tracker.step(make_batch(T0 + k * FRAME, dets, seq=k))
        if k in (int(1.5 / FRAME), int(5.5 / FRAME) - 1):  # before they meet, at the end
            x = {tr.id: tr.x for tr in out.tracks}
            owners.append([min(x, key=lambda i: abs(x[i] - p)) for p in (a, b)])
    assert len(set(owners[0])) == 2
    assert (owners[1] == owners[0]) is kept


def _widening(
    loglik: list[list[float]],
    rows: list[int],
    cols: list[int],
    gated: list[list[bool]],
    confirmed: list[bool],
    blob: list[bool] | None = None,
    factor: float = 10.0,
) -> np.ndarray:
    """The factor ``shared_noise`` puts on each pair's (unit) noise."""
    r = np.repeat(np.eye(2)[None], len(rows), axis=0)
    out = shared_noise(
        r,
        np.array(rows),
        np.array(cols),
        np.array(blob if blob is not None else [False] * len(rows)),
        np.array(gated),
        np.array(confirmed),
        factor,
        -2.0 * np.array(loglik),  # the association cost: -2 log-likelihood
    )
    return out[:, 0, 0]


def test_a_detection_two_tracks_share_equally_counts_half_when_each_has_its_own() -> None:
    # two tracks, two detections, each in both gates: which is which is uncertain, but
    # each track has a detection, so neither is two people in one blob
    ll = [[-1.0, -1.0], [-1.0, -1.0]]
    widen = _widening(ll, [0, 1], [0, 1], [[True, True], [True, True]], [True, True])
    np.testing.assert_allclose(widen, [2.0, 2.0])


def test_the_widening_is_the_inverse_odds_of_the_pairs_own_track() -> None:
    # detection 0 is three times likelier under track 0 than under track 1: odds 3/4
    ll = [[math.log(3.0), -5.0], [0.0, 0.0]]
    widen = _widening(ll, [0, 1], [0, 1], [[True, False], [True, True]], [True, True])
    assert widen[0] == pytest.approx(4.0 / 3.0)
    assert widen[1] == pytest.approx(1.0)  # detection 1 is in track 1's gate alone


def test_an_unlikely_pair_is_widened_by_the_factor_at_most() -> None:
    ll = [[-30.0, 0.0], [0.0, 0.0]]
    widen = _widening(ll, [0, 1], [0, 1], [[True, True], [True, True]], [True, True])
    assert widen[0] == pytest.approx(10.0)


def test_a_detection_a_rival_with_no_detection_of_its_own_may_share_is_widened_fully() -> None:
    # track 1 has no detection in this frame: detection 0 may be both people in a blob
    ll = [[0.0], [0.0]]
    widen = _widening(ll, [0], [0], [[True], [True]], [True, True])
    assert widen[0] == pytest.approx(10.0)
    # an explicit blob share is widened fully too
    widen = _widening(ll, [0, 1], [0, 0], [[True], [True]], [True, True], blob=[False, True])
    np.testing.assert_allclose(widen, 10.0 + BLOB_RADIUS_M**2)  # plus a body's radius


def test_without_likelihoods_every_shared_detection_is_widened_by_the_factor() -> None:
    r = np.repeat(np.eye(2)[None], 2, axis=0)
    gated = np.ones((2, 2), dtype=bool)
    out = shared_noise(r, np.array([0, 1]), np.array([0, 1]), np.zeros(2, bool), gated,
                       np.array([True, True]), 10.0)  # fmt: skip
    np.testing.assert_allclose(out[:, 0, 0], [10.0, 10.0])


def test_a_tentative_tracks_detection_is_weighed_against_the_confirmed_rivals() -> None:
    # detection 2 is in the gates of confirmed tracks 0 and 1, each with a detection of
    # its own, and of tentative track 2, whose it is: its own odds count once, 1 in 3
    ll = np.zeros((3, 3)).tolist()
    gated = [[True, False, True], [False, True, True], [False, False, True]]
    widen = _widening(ll, [0, 1, 2], [0, 1, 2], gated, [True, True, False])
    np.testing.assert_allclose(widen, [1.0, 1.0, 3.0])
