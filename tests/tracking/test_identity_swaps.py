"""Identities that motion exchanged where two people met are put back by their looks."""

from __future__ import annotations

import numpy as np
import pytest

from openptrack_py.tracking.identity.models import Side
from openptrack_py.tracking.identity.swaps import SwapWatch
from tests.tracking.helpers import FRAME
from tests.tracking.test_identity import _warm_up, batch, identity_tracker, look, person


def _part_unseen(tracker, rng, t0, k0, crossed, colours=(2, 11)):
    """Two people walk into one blob, stand 1 s and part; their colours are not seen
    (lit from behind, say) from 0.5 s before the blob until 1.5 s after it, so motion
    alone carries the tracks through. ``crossed``: the person who came from the left
    leaves to the right. Returns the stable ids on the left and on the right at the end.
    """
    out = None
    phases = ((45, 1.2, 0.2), (30, 0.0, 0.0), (45, 0.2, 1.2), (60, 1.2, 1.2))
    k = k0
    for p, (frames, h0, h1) in enumerate(phases):
        for j in range(frames):
            t = t0 + (k - k0) * FRAME
            half = h0 + (h1 - h0) * j / frames
            hidden = (p == 0 and j >= 30) or p == 1 or (p == 2 and j < 45)
            sa, sb = (None, None) if hidden else (look(colours[0], rng), look(colours[1], rng))
            if p >= 2 and crossed:
                sa, sb = sb, sa
            if half:
                dets = (person(5.0 - half, 8.0, sa, u=300), person(5.0 + half, 8.0, sb, u=600))
            else:
                dets = (person(5.0, 8.0, None, u=450),)
            out = tracker.step(batch(t, dets, k))
            k += 1
    return (
        {tr.stable_id for tr in out.tracks if tr.x < 5.0 and tr.y > 7},
        {tr.stable_id for tr in out.tracks if tr.x > 5.0 and tr.y > 7},
    )


def _scene(crossed: bool, colours=(2, 11)):
    rng = np.random.default_rng(21)
    tracker = identity_tracker()
    _, t = _warm_up(tracker, rng)
    out = None
    for k in range(60):  # each one's identity while they stand apart
        dets = (
            person(3.8, 8.0, look(colours[0], rng), u=300),
            person(6.2, 8.0, look(colours[1], rng), u=600),
        )
        out = tracker.step(batch(t + k * FRAME, dets, 1000 + k))
    before = {tr.x < 5.0: tr.stable_id for tr in out.tracks if tr.y > 7}
    left, right = _part_unseen(tracker, rng, t + 2.0, 2000, crossed, colours)
    return tracker, before, left, right


@pytest.mark.parametrize("crossed", [False, True])
def test_identities_motion_exchanged_in_a_blob_are_put_back_by_colour(crossed: bool) -> None:
    """The tracks come out of the blob the same way whoever went where (no colours were
    seen): one of the two ways they are exchanged, and colours put them back."""
    tracker, before, left, right = _scene(crossed)
    went_left = before[not crossed]  # the person now on the left
    assert left == {went_left}
    assert right == {before[crossed]}
    assert tracker.identity.counters["swapped_back"] == int(crossed)


def test_people_dressed_alike_are_never_swapped() -> None:
    """Where the looks cannot tell the two apart nothing is swapped: identity stays
    with motion, right or wrong."""
    for crossed in (False, True):
        tracker, before, left, right = _scene(crossed, colours=(5, 5))
        assert tracker.identity.counters["swapped_back"] == 0
        assert left == {before[True]} and right == {before[False]}


def _side(values: list[float]) -> Side:
    sig = np.array([[v, 1.0 - v] for v in values])
    n = len(values)
    return Side(sig, np.ones(n, dtype=bool), np.zeros((n, 0)), np.zeros(n))


def _llr(a: Side, b: Side) -> np.ndarray:
    """Toy likelihood ratio: +2 for the same look, -2 for another."""
    return np.where(np.abs(a.sig[:, 0] - b.sig[:, 0]) < 0.5, 2.0, -2.0)


def test_a_watch_decides_once_and_survives_a_snapshot() -> None:
    watch = SwapWatch(margin=2.0, window_s=10.0, min_observations=3)
    watch.meet([(1, 2)], 0.0, lambda ids: _side([0.0 if i == 1 else 1.0 for i in ids]))
    saved = watch.state()
    for k in range(3):  # track 1 now looks like 2 and 2 like 1
        watch.observe(np.array([1, 2]), _side([1.0, 0.0]), 1.0 + k, _llr)
        decided = watch.decide(1.0 + k, np.array([1, 2]))
        assert [p for p, _ in decided] == ([(1, 2)] if k == 2 else [])
    assert not watch.watches
    watch.restore(saved)
    for k in range(3):  # as they were: settled, nothing to swap
        watch.observe(np.array([1, 2]), _side([0.0, 1.0]), 1.0 + k, _llr)
        assert watch.decide(1.0 + k, np.array([1, 2])) == []
    assert not watch.watches


def test_a_watch_is_forgotten_when_a_track_ends_or_the_window_passes() -> None:
    watch = SwapWatch(margin=2.0, window_s=10.0, min_observations=3)
    watch.meet([(1, 2), (3, 4)], 0.0, lambda ids: _side([0.0] * len(ids)))
    assert watch.decide(0.5, np.array([1, 2, 3])) == []
    assert set(watch.watches) == {(1, 2)}
    assert watch.decide(11.0, np.array([1, 2])) == []
    assert not watch.watches


def test_a_track_is_swapped_at_most_once_per_step_by_its_most_decisive_pair() -> None:
    """Three tracks that all exchanged people: one pair is put right, not three."""
    watch = SwapWatch(margin=2.0, window_s=10.0, min_observations=1)
    looks = {1: 0.0, 2: 1.0, 3: 0.5}
    watch.meet([(1, 2), (1, 3), (2, 3)], 0.0, lambda ids: _side([looks[i] for i in ids]))

    def llr(a: Side, b: Side) -> np.ndarray:
        return -4.0 * np.abs(a.sig[:, 0] - b.sig[:, 0]) + 2.0

    # track 1 now looks like 2, track 2 like 3, track 3 like 1
    watch.observe(np.array([1, 2, 3]), _side([1.0, 0.5, 0.0]), 1.0, llr)
    decided = watch.decide(1.0, np.array([1, 2, 3]))
    ids = [i for pair, _ in decided for i in pair]
    assert len(decided) == 1 and len(ids) == len(set(ids))
    assert decided[0][0] in {(1, 2), (1, 3)}  # the two pairs that score 4 (the third 0)
    assert not watch.watches


def test_a_restored_watch_decides_as_the_uninterrupted_one() -> None:
    """A pair past its window is never decided, whenever the last sweep was (a
    late-batch replay restores mid-run and must end where the run would have)."""

    def run(restore_at: float | None) -> list:
        watch = SwapWatch(margin=2.0, window_s=10.0, min_observations=3)
        watch.meet([(1, 2)], 0.0, lambda ids: _side([0.0 if i == 1 else 1.0 for i in ids]))
        decided = []
        for k in range(110):
            t = 0.1 * (k + 1)
            if restore_at is not None and abs(t - restore_at) < 1e-9:
                watch.restore(watch.state())
            if t > 10.05:  # the exchanged looks are seen only after the window
                watch.observe(np.array([1, 2]), _side([1.0, 0.0]), t, _llr)
            decided += [p for p, _ in watch.decide(t, np.array([1, 2]))]
        return decided

    assert run(None) == run(10.1) == []


def test_a_state_is_untouched_by_what_the_watch_sees_after_it() -> None:
    """States share the watches until they change (one is taken every step): what is
    observed after a state, or after a restore, must not leak into the state."""
    watch = SwapWatch(margin=2.0, window_s=10.0, min_observations=3)
    watch.meet([(1, 2)], 0.0, lambda ids: _side([0.0 if i == 1 else 1.0 for i in ids]))
    saved = watch.state()
    for _restore in range(2):
        for k in range(2):  # exchanged looks, one observation short of a decision
            watch.observe(np.array([1, 2]), _side([1.0, 0.0]), 1.0 + k, _llr)
            assert watch.decide(1.0 + k, np.array([1, 2])) == []
        watch.meet([(1, 2)], 0.5, lambda ids: _side([0.0] * len(ids)))  # met again
        watch.restore(saved)
        assert saved[0][(1, 2)].count.tolist() == [0.0, 0.0]
        assert saved[0][(1, 2)].met == 0.0
    watch.observe(np.array([1, 2]), _side([1.0, 0.0]), 3.0, _llr)
    assert watch.decide(3.0, np.array([1, 2])) == []  # one observation since the state
