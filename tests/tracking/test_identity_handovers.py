"""A track that went on with someone else after a gap or a meeting is split off by its looks."""

from __future__ import annotations

import numpy as np
import pytest

from openptrack_py.tracking.identity.handovers import GapWatch
from openptrack_py.tracking.identity.models import Side
from tests.tracking.helpers import FRAME
from tests.tracking.test_identity import _warm_up, batch, identity_tracker, look, person, walker


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


def test_a_meeting_starts_a_watch_with_the_looks_from_before_the_first_meeting() -> None:
    """Each meeting keeps the watch open and starts its evidence again; its looks and
    the time its person was last surely followed stay those of the first meeting; an
    exchange forgets it."""
    watch = GapWatch(margin=1.0, window_s=2.0, min_observations=10)
    first = Side(np.ones((1, 2)), np.ones(1, dtype=bool), np.zeros((1, 0)), np.zeros(1))
    watch.met(np.array([3, 3]), 0.0, lambda ids: first)  # one track in two pairs
    watch.observe(np.array([3]), _side(1), lambda a, b: np.full(len(a.sig), -2.0))
    assert watch.leaning(3) == -2.0
    watch.met(np.array([3]), 1.5, lambda ids: _side(len(ids)))
    assert list(watch.watches) == [3] and watch.leaning(3) == 0.0
    assert watch.watches[3].before.sig.tolist() == [[1.0, 1.0]]
    assert watch.watches[3].lost_at == 0.0
    assert watch.decide(3.0, np.array([3])) == {} and 3 in watch.watches  # 1.5 s + 2 s
    assert watch.decide(3.6, np.array([3])) == {} and watch.watches == {}
    watch.met(np.array([3, 4]), 4.0, lambda ids: _side(len(ids)))
    watch.forget((3, 4))
    assert watch.watches == {}


def test_a_split_waits_while_the_track_is_held_and_goes_ahead_after() -> None:
    """A held track (one it met looks unlike itself too: an exchange the swap watch puts
    right) is not split, its watch open until its window ends."""
    watch, decided = _watch_with(-2.0, observations=10)
    assert decided == {7: 0.1}
    watch = GapWatch(margin=1.0, window_s=5.0, min_observations=10)
    ids, ready = np.array([7]), np.array([True])
    for t in (0.0, 0.1, 1.0):
        watch.seen(ids, ready, t, lambda ids: _side(len(ids)))
    for _ in range(10):
        watch.observe(ids, _side(1), lambda a, b: np.full(len(a.sig), -2.0))
    assert watch.decide(2.0, ids, held=lambda tid: True) == {} and 7 in watch.watches
    assert watch.decide(2.1, ids) == {7: 0.1}
    watch.seen(ids, ready, 3.0, lambda ids: _side(len(ids)))  # a new gap
    for _ in range(10):
        watch.observe(ids, _side(1), lambda a, b: np.full(len(a.sig), -2.0))
    assert watch.decide(8.1, ids, held=lambda tid: True) == {} and watch.watches == {}


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


WALK_S = 12.0
"""How long the two walk apart first: the newcomer's track is then no longer young
(:attr:`IdentityConfig.reid_window_s`), so cannot take back a pooled identity itself."""


def _lanes(s: float) -> tuple[float, float]:
    """The lateral places (y) of the person in colour 4 and of the newcomer at ``s``."""
    s -= WALK_S
    if s < 0.0:
        return 4.5, 6.0
    if s < 1.0:  # the newcomer comes alongside
        return 4.5, 6.0 - 1.1 * s
    if s < 1.5:  # they change sides
        return 4.9, 4.5
    return 4.9 + 1.2 * min(s - 1.5, 0.5), 4.5


def _change_sides() -> tuple[object, dict[str, int], int | None]:
    """The person in colour 4 and a newcomer in colour 13 walk side by side and change
    sides unseen in colour; as they part, the newcomer leaves view. Returns the
    tracker, the two people's stable ids before they met (``mine``, ``new``) and that
    of the track following the person in colour 4 just after (``parted``), and the
    stable id of the track following them at the end."""
    rng = np.random.default_rng(13)
    tracker = identity_tracker()
    out, t = _warm_up(tracker, rng, frames=60)
    ids: dict[str, int] = {}
    for j in range(int((WALK_S + 8.0) / FRAME)):
        s = j * FRAME
        ya, yb = _lanes(s)
        unseen = WALK_S + 0.5 < s < WALK_S + 2.2
        dets = [walker(i, t + s, look(3 * i + 1, rng)) for i in (0, 2)]
        dets.append(person(1.5 + 0.1 * s, ya, None if unseen else look(4, rng)))
        if s < WALK_S + 1.5:
            dets.append(person(1.5 + 0.1 * s, yb, None if unseen else look(13, rng), u=700))
        out = tracker.step(batch(t + s, tuple(dets), 1000 + j))
        if abs(s - (WALK_S - 0.5)) < FRAME / 2:
            ids = {
                ("mine" if tr.y < 5.2 else "new"): tr.stable_id
                for tr in out.tracks
                if 4.0 < tr.y < 6.5
            }
        if abs(s - (WALK_S + 2.3)) < FRAME / 2:  # parted, seen in colour again
            ids["parted"] = next(tr.stable_id for tr in out.tracks if 5.2 < tr.y < 6.5)
    end = [tr.stable_id for tr in out.tracks if 4.0 < tr.y < 6.5]
    return tracker, ids, end[0] if len(end) == 1 else None


def test_a_track_gone_on_with_the_person_it_met_is_split_and_its_person_reidentified() -> None:
    """Where two people change sides, their tracks go on with each other (motion cannot
    tell), and the newcomer leaves view before the exchange can be put right: the
    person in colour 4 is followed by the newcomer's track. Its looks since they met
    split it, and the split-off track takes back the person's own identity, pooled when
    the track that went with the newcomer was given up."""
    tracker, ids, now = _change_sides()
    assert ids["mine"] != ids["new"] and ids["parted"] == ids["new"]
    assert now == ids["mine"]
    assert tracker.counters["tracks_split"] == tracker.identity.counters["handed_over"] == 1
    assert tracker.identity.counters["reidentified"] == 1
