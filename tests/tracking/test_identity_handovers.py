"""A track that came back from a gap following someone else is split off by its looks."""

from __future__ import annotations

import numpy as np
import pytest

from openptrack_py.tracking.identity.handovers import GapWatch
from openptrack_py.tracking.identity.models import Side
from tests.tracking.helpers import FRAME
from tests.tracking.test_identity import _warm_up, batch, identity_tracker, look, walker


def _side(n: int) -> Side:
    return Side(np.zeros((n, 2)), np.ones(n, dtype=bool), np.zeros((n, 0)), np.zeros(n))


def _watch_with(llr: float, observations: int, window_s: float = 5.0) -> tuple[GapWatch, dict]:
    """A track seen at 0 s and 0.1 s, then again from 1 s on, each observation giving ``llr``."""
    watch = GapWatch(margin=1.0, window_s=window_s, min_observations=10)
    ids, ready = np.array([7]), np.array([True])
    for t in (0.0, 0.1, 1.0):
        watch.seen(ids, ready, t, lambda ids: _side(len(ids)))
    decided: dict = {}
    for k in range(observations):
        watch.observe(ids, _side(1), lambda a, b: np.full(len(a.sig), llr))
        decided.update(watch.decide(1.0 + 0.1 * k, ids))
    return watch, decided


def test_a_gap_starts_a_watch_only_for_known_tracks_and_only_after_gap_s() -> None:
    watch = GapWatch(margin=1.0, window_s=5.0, min_observations=10)
    looks = lambda ids: _side(len(ids))  # noqa: E731
    watch.seen(np.array([1, 2]), np.array([True, False]), 0.0, looks)
    watch.seen(np.array([1, 2]), np.array([True, False]), 0.4, looks)  # 0.4 s: no gap
    assert watch.watches == {}
    watch.seen(np.array([1, 2]), np.array([True, False]), 1.0, looks)  # 0.6 s: a gap
    assert list(watch.watches) == [1]  # track 2's looks are not known well enough
    assert watch.watches[1].lost_at == 0.4 and watch.watches[1].since == 1.0


@pytest.mark.parametrize(
    ("llr", "split"), [(-2.0, True), (2.0, False), (0.0, False)], ids=["other", "same", "alike"]
)
def test_a_watch_splits_only_when_the_looks_after_the_gap_are_someone_elses(
    llr: float, split: bool
) -> None:
    """Ten observations whose mean is below -margin split the track (reporting when its
    person was lost); above margin the watch settles; near 0 it waits, then expires."""
    watch, decided = _watch_with(llr, observations=10)
    assert decided == ({7: 0.1} if split else {})
    assert (7 in watch.watches) == (llr == 0.0)
    _, early = _watch_with(-2.0, observations=9)
    assert early == {}  # nine observations decide nothing
    watch, _ = _watch_with(0.0, observations=10, window_s=0.5)
    assert watch.watches == {}  # undecided past its window: dropped


def _newcomer_where_one_left(colour: int) -> tuple[object, set[int], set[int], int]:
    """Three people walk in their colours; the one in colour 4 is not seen for 1 s,
    then someone in ``colour`` walks on where they were. Returns the tracker, the ids
    and stable ids of that person's track before the gap, those of the track at that
    place 4 s after it, and the person's stable id."""
    rng = np.random.default_rng(11)
    tracker = identity_tracker()
    out, t = _warm_up(tracker, rng)
    mine = [tr for tr in out.tracks if round(tr.y) == 4]
    assert len(mine) == 1
    k = 1000
    for j in range(int(5.0 / FRAME)):
        tt = t + j * FRAME
        dets = [walker(i, tt, look(3 * i + 1, rng)) for i in (0, 2)]
        if j * FRAME >= 1.0:
            dets.append(walker(1, tt, look(colour, rng)))
        out = tracker.step(batch(tt, tuple(dets), k))
        k += 1
    now = [tr for tr in out.tracks if round(tr.y) == 4]
    assert len(now) == 1
    return tracker, {mine[0].id, now[0].id}, {mine[0].stable_id, now[0].stable_id}, mine[0].id


def test_a_track_that_took_someone_else_after_a_gap_is_split_and_its_identity_pooled() -> None:
    """The leaver's track takes the newcomer (motion cannot tell); their looks split it:
    the newcomer gets a new track and identity, the leaver's identity waits in the pool."""
    tracker, ids, stable, leaver = _newcomer_where_one_left(colour=13)
    assert len(ids) == 2 and len(stable) == 2
    assert tracker.counters["tracks_split"] == tracker.identity.counters["handed_over"] == 1
    assert leaver in {e.stable for e in tracker.identity.pool}


def test_a_person_back_from_a_gap_in_their_own_looks_keeps_their_track() -> None:
    tracker, ids, stable, _ = _newcomer_where_one_left(colour=4)
    assert len(ids) == 1 and len(stable) == 1
    assert tracker.counters["tracks_split"] == 0
