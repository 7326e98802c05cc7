"""The identity role: learned likelihoods, appearance in association, re-identification,
names, replay and checkpoints, on hand-built detections whose truth is known."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from openptrack_py.config import TrackerConfig
from openptrack_py.config.identity import IdentityConfig
from openptrack_py.errors import ConfigError
from openptrack_py.messages.detection import Detection, DetectionBatch
from openptrack_py.tracking import build_tracker
from openptrack_py.tracking.identity import (
    AppearanceIdentity,
    Roster,
    RosterEntry,
    load_roster,
    save_roster,
)
from openptrack_py.tracking.identity.heights import HeightBias
from openptrack_py.tracking.identity.likelihood import DistanceLikelihood, hellinger
from openptrack_py.tracking.identity.models import PooledIdentity
from openptrack_py.tracking.identity.returns import ReturnRate, link_posterior
from openptrack_py.tracking.identity.roster import entry_from_looks
from openptrack_py.tracking.roster_service import RosterKeeper, roster_request
from openptrack_py.tracking.state import Looks
from tests.tracking.helpers import FRAME, T0

BINS = 19


def look(hue_bin: int, rng: np.random.Generator, noise: float = 0.15) -> tuple[int, ...]:
    """A noisy signature of clothing mostly in one bin (and a neighbour's tail)."""
    h = np.full(BINS, 0.02)
    h[hue_bin] += 0.7
    h[(hue_bin + 1) % BINS] += 0.2
    h *= rng.gamma(1 / noise**2, noise**2, BINS)
    return tuple(np.round(h / h.sum() * 255).astype(int).tolist())


def person(x, y, sig, conf=0.9, u=None, face=None, height=1.75):
    u = int(100 + 60 * x) if u is None else u
    return Detection(
        x=float(x), y=float(y), z=0.9, height=float(height), confidence=conf, distance=3.0,
        bbox=(u, 50, 40, 150), appearance=sig, face=face,
    )  # fmt: skip


def walker(i: int, t: float, sig, **kw) -> Detection:
    """Person ``i`` of a scene's row of people, each swaying along their own line."""
    return person(1.0 + 0.8 * i + 0.3 * math.sin(t - T0 + i), 2.0 + 2.5 * i, sig, **kw)


def batch(t, dets, k, sensor="s0"):
    return DetectionBatch(sensor_id=sensor, seq=k, stamp=t, frame_id="world", detections=dets)


def identity_tracker(**identity) -> object:
    cfg = TrackerConfig(identity={"enabled": True, "height_weight": 1.0, **identity})
    return build_tracker(cfg)


def _warm_up(tracker, rng, frames=300, k0=0, t0=T0):
    """Three people walking apart, each in their own colour: the likelihood learns."""
    out = None
    for k in range(frames):
        t = t0 + k * FRAME
        dets = tuple(walker(i, t, look(3 * i + 1, rng)) for i in range(3))
        out = tracker.step(batch(t, dets, k0 + k))
    return out, t0 + frames * FRAME


# -------------------------------------------------------------- the likelihood


def test_the_likelihood_has_no_opinion_until_it_has_learned() -> None:
    model = DistanceLikelihood(max_llr=3.0)
    assert not model.ready
    assert (model.llr(np.linspace(0, 1, 11)) == 0).all()
    rng = np.random.default_rng(1)
    model.learn(rng.uniform(0.0, 0.3, 400), rng.uniform(0.4, 1.0, 400))
    assert model.ready
    assert model.llr(np.array([0.1]))[0] > 2.0
    assert model.llr(np.array([0.8]))[0] < -2.0
    assert model.separation() > 1.0
    copy = DistanceLikelihood(3.0)
    copy.restore(model.state())
    np.testing.assert_array_equal(
        copy.llr(np.linspace(0, 1, 50)), model.llr(np.linspace(0, 1, 50))
    )


def test_where_everyone_looks_alike_the_likelihood_stays_near_zero() -> None:
    model = DistanceLikelihood(max_llr=3.0)
    rng = np.random.default_rng(2)
    model.learn(rng.uniform(0.0, 0.5, 2000), rng.uniform(0.0, 0.5, 2000))
    assert np.abs(model.llr(np.linspace(0.0, 0.5, 20))).max() < 0.6
    assert model.separation() < 0.1


def test_a_look_farther_from_the_model_never_counts_more_for_the_person() -> None:
    # many different-person samples, few same-person ones, none of either far out: the
    # far bins hold only the prior, which on its own favoured the rarer kind (+2.5 nats
    # at a distance no sample reached)
    model = DistanceLikelihood(max_llr=3.0)
    rng = np.random.default_rng(3)
    model.learn(rng.uniform(0.0, 0.3, 100), rng.uniform(0.3, 0.6, 2000))
    table = model.llr(np.linspace(0.0, 1.0, 101))
    assert (np.diff(table) <= 1e-12).all()
    assert model.llr(np.array([0.9]))[0] < -1.0
    assert model.llr(np.array([0.1]))[0] > 2.0


def test_hellinger_is_zero_for_equal_and_one_for_disjoint_histograms() -> None:
    a = np.array([[0.5, 0.5, 0.0, 0.0]])
    b = np.array([[0.5, 0.5, 0.0, 0.0], [0.0, 0.0, 0.5, 0.5]])
    np.testing.assert_allclose(hellinger(a, b), [[0.0, 1.0]], atol=1e-9)


def test_looks_mark_the_farther_of_two_overlapping_boxes_unclean() -> None:
    rng = np.random.default_rng(0)
    near = replace(person(1, 1, look(2, rng), u=100), distance=2.0)
    far = replace(person(1.2, 1.5, look(5, rng), u=120), distance=4.0)
    apart = replace(person(4, 1, look(8, rng), u=400), distance=3.0)
    looks = Looks.of([near, far, apart])
    assert looks.clean.tolist() == [True, False, True]
    np.testing.assert_allclose(looks.signature.sum(axis=1), 1.0)


# ------------------------------------------------------------------ association


def _crossing(tracker, rng, t0, k0, same_colour=False):
    """Two people walk towards each other along one line, meet and go on (or turn back).

    They turn back at the meeting point: motion alone predicts that they continue and
    swap; their colours say otherwise. Returns each person's output ids after the meeting.
    """
    ids_after = {0: set(), 1: set()}
    n = 90
    for k in range(n):
        t = t0 + k * FRAME
        s = k / (n - 1)
        # approach (first half) and turn back (second half): mirror paths
        d = 1.2 * (1 - 2 * s) if s < 0.5 else 1.2 * (2 * s - 1)
        xa, xb = 5.0 - max(d, 0.05), 5.0 + max(d, 0.05)
        sig_b = look(2, rng) if same_colour else look(11, rng)
        dets = (person(xa, 8.0, look(2, rng), u=300), person(xb, 8.0, sig_b, u=600))
        out = tracker.step(batch(t, dets, k0 + k))
        if s > 0.75:
            for tr in out.tracks:
                side = 0 if tr.x < 5.0 else 1
                ids_after[side].add(tr.stable_id)
    return ids_after


def test_identity_labels_every_track_with_a_stable_id() -> None:
    rng = np.random.default_rng(3)
    tracker = identity_tracker()
    out, _ = _warm_up(tracker, rng)
    assert len(out.tracks) == 3
    assert all(tr.stable_id == tr.id for tr in out.tracks)
    assert tracker.identity.colour.ready


def test_appearance_never_admits_a_pair_the_gate_rejects() -> None:
    rng = np.random.default_rng(4)
    tracker = identity_tracker(appearance_weight=10.0)
    out, t = _warm_up(tracker, rng)
    ids = {tr.id for tr in out.tracks}
    # a detection 3 m from every track, in the colours of track 1's person
    far = person(9.0, 9.0, look(1, rng))
    out = tracker.step(batch(t, (far,), 10_000))
    assert all(abs(tr.x - 9.0) > 1.0 for tr in out.tracks if tr.id in ids)


# ------------------------------------------------------------- re-identification


def _leave_and_return(tracker, rng, t, k0, colour, where=(6.0, 6.0), gone_s=20.0, colour_every=1):
    """The person of ``colour`` comes back after ``gone_s`` while the others stay.

    Back, their colours are seen in one frame of ``colour_every``; the other frames
    carry only a face embedding, which says nothing yet (no faces were seen before).
    """
    out = None
    k = k0
    # the others keep walking while the person is away; the person is absent
    steps = int(gone_s / (5 * FRAME))
    for j in range(steps):
        tt = t + j * 5 * FRAME
        dets = tuple(person(1.0, 2.0 + 2.5 * i, look(3 * i + 1, rng)) for i in (0, 2))
        out = tracker.step(batch(tt, dets, k))
        k += 1
    t = t + steps * 5 * FRAME
    for j in range(120):
        tt = t + j * FRAME
        dets = tuple(person(1.0, 2.0 + 2.5 * i, look(3 * i + 1, rng)) for i in (0, 2))
        sig, face = (look(colour, rng), None) if j % colour_every == 0 else (None, _face(9, rng))
        dets += (person(where[0] + 0.01 * j, where[1], sig, u=700, face=face),)
        out = tracker.step(batch(tt, dets, k))
        k += 1
    return out


def test_a_person_who_returns_gets_their_stable_id_back() -> None:
    rng = np.random.default_rng(5)
    tracker = identity_tracker()
    out, t = _warm_up(tracker, rng)
    before = {round(tr.y): tr.stable_id for tr in out.tracks}
    out = _leave_and_return(tracker, rng, t, 1000, colour=4)
    back = [tr for tr in out.tracks if tr.x > 5.0]
    assert len(back) == 1
    assert back[0].id != before[4]  # a new track...
    assert back[0].stable_id == before[4]  # ...with the old identity
    assert tracker.identity.counters["reidentified"] == 1


def test_frames_without_a_clean_colour_do_not_water_down_a_return() -> None:
    rng = np.random.default_rng(5)
    tracker = identity_tracker()
    out, t = _warm_up(tracker, rng)
    before = {round(tr.y): tr.stable_id for tr in out.tracks}
    out = _leave_and_return(tracker, rng, t, 1000, colour=4, colour_every=4)
    back = [tr for tr in out.tracks if tr.x > 5.0]
    assert len(back) == 1 and back[0].stable_id == before[4]


def _seen_last_under_another_light(visit_rate: float) -> tuple[int, int]:
    """The person in colour 4 is seen, in their last two seconds, in another sensor's cast.

    Returns the stable id they had and the one they come back with.
    """
    rng = np.random.default_rng(5)
    tracker = identity_tracker(visit_rate=visit_rate, height_weight=0.0)
    out, t = _warm_up(tracker, rng, frames=450)
    before = {round(tr.y): tr.stable_id for tr in out.tracks}
    hues = (1, 6, 7)  # person 1's 4 seen as 6
    for k in range(60):  # by the door, under a sensor that renders their hue two bins off
        dets = tuple(person(1.0, 2.0 + 2.5 * i, look(hues[i], rng)) for i in range(3))
        tracker.step(batch(t + k * FRAME, dets, 500 + k, sensor="s1"))
    out = _leave_and_return(tracker, rng, t + 60 * FRAME, 1000, colour=4)
    (back,) = [tr for tr in out.tracks if tr.x > 5.0]
    return before[4], back.stable_id


def test_a_pooled_look_describes_the_visit_not_the_last_seconds() -> None:
    """A model that remembered only the last 100 looks would pool the door's light."""
    left, back = _seen_last_under_another_light(IdentityConfig().visit_rate)
    assert back == left
    left, back = _seen_last_under_another_light(0.01)
    assert back != left


def test_a_person_missed_at_one_return_is_taken_back_at_the_next() -> None:
    """A return not taken back leaves one person two pooled identities; the newest stays.

    The first return is kept from linking (a posterior bar nothing reaches), as when
    the evidence was too weak in time. Left side by side, the person's two pooled
    identities would split the posterior at every later return; the newer replaces
    the older, so the next return takes back the identity clients saw last.
    """
    rng = np.random.default_rng(5)
    tracker = identity_tracker()
    out, t = _warm_up(tracker, rng)
    first = next(tr.stable_id for tr in out.tracks if round(tr.y) == 4)
    ident = tracker.identity
    default = ident.cfg
    ident.cfg = default.model_copy(update={"reid_min_posterior": 0.999})
    out = _leave_and_return(tracker, rng, t, 1000, colour=4)
    missed = next(tr for tr in out.tracks if tr.x > 5.0)
    assert missed.stable_id == missed.id != first  # not taken back
    for k in range(150):  # they leave again, and their track ends
        dets = tuple(person(1.0, 2.0 + 2.5 * i, look(3 * i + 1, rng)) for i in (0, 2))
        out = tracker.step(batch(out.stamp + FRAME, dets, 2000 + k))
    assert missed.id not in {tr.id for tr in out.tracks}
    ident.cfg = default
    out = _leave_and_return(tracker, rng, out.stamp + FRAME, 3000, colour=4)
    back = [tr for tr in out.tracks if tr.x > 5.0]
    assert len(back) == 1 and back[0].id != missed.id
    assert back[0].stable_id == missed.stable_id
    assert first not in {e.stable for e in ident.pool}


def test_a_look_alike_does_not_replace_two_people_who_were_there_together() -> None:
    """Two people dressed alike leave; a third dressed alike comes and goes unlinked.

    The third track looks like both, but both were there at the same time: two people,
    of whom it can be at most one. Both identities stay in the pool.
    """
    rng = np.random.default_rng(9)
    tracker = identity_tracker()
    colours = (4, 4, 13, 16)

    def frame(t, k, who, extra=()):
        dets = tuple(walker(i, t, look(colours[i], rng)) for i in who)
        return tracker.step(batch(t, dets + extra, k))

    for k in range(300):
        out = frame(T0 + k * FRAME, k, range(4))
    alike = {tr.stable_id for tr in out.tracks if tr.y < 5.0}
    t = out.stamp
    for k in range(120):  # the two leave for 20 s
        out = frame(t + 5 * (k + 1) * FRAME, 300 + k, (2, 3))
    t = out.stamp
    for k in range(120):  # a third dressed alike comes, and goes
        third = person(6.0 + 0.01 * k, 6.0, look(4, rng), u=700)
        out = frame(t + (k + 1) * FRAME, 420 + k, (2, 3), (third,))
    stranger = next(tr for tr in out.tracks if tr.x > 5.0)
    assert stranger.stable_id == stranger.id  # one of two: no link
    t = out.stamp
    for k in range(150):
        out = frame(t + (k + 1) * FRAME, 540 + k, (2, 3))
    pooled = {e.stable for e in tracker.identity.pool}
    assert len(alike) == 2 and alike <= pooled and stranger.id in pooled


def _alike_but_not_as_tall(tracker, rng, back_height, stoop_m=0.0) -> tuple[int, int]:
    """Three people dressed alike, 1.55, 1.75 and 1.95 m tall; the middle one leaves
    and someone ``back_height`` tall comes back. Returns the middle one's stable id and
    the stable id of whoever came back. ``stoop_m``: how much lower the middle one is
    seen in their last 2 s (bending to pick up a bag on the way out)."""
    heights = [1.55, 1.75, 1.95]

    def frame(t, k, who, extra=()):
        dets = tuple(
            walker(i, t, look(7, rng), height=heights[i] + rng.normal(0.0, 0.02))
            for i in who
        ) + extra  # fmt: skip
        return tracker.step(batch(t, dets, k))

    for k in range(300):
        if k == 240:
            heights[1] -= stoop_m
        out = frame(T0 + k * FRAME, k, (0, 1, 2))
    before = min(out.tracks, key=lambda tr: abs(tr.y - 4.5)).stable_id
    t = T0 + 300 * FRAME
    for k in range(120):  # 20 s away
        out = frame(t + 5 * k * FRAME, 300 + k, (0, 2))
    t += 600 * FRAME
    for k in range(120):
        back = person(6.0 + 0.01 * k, 6.0, look(7, rng), u=700,
                      height=back_height + rng.normal(0.0, 0.02))  # fmt: skip
        out = frame(t + k * FRAME, 420 + k, (0, 2), (back,))
    return before, next(tr.stable_id for tr in out.tracks if tr.x > 5.0)


def test_height_brings_back_a_person_whose_colours_tell_nothing() -> None:
    before, back = _alike_but_not_as_tall(identity_tracker(), np.random.default_rng(21), 1.75)
    assert back == before
    # without heights, colours alone cannot say it is them: a new identity
    tracker = identity_tracker(height_weight=0.0)
    before, back = _alike_but_not_as_tall(tracker, np.random.default_rng(21), 1.75)
    assert back != before


def test_a_pooled_height_is_the_visits_not_the_last_seconds() -> None:
    """A model that remembered only the last 100 heights would pool the stoop."""
    tracker = identity_tracker()
    before, back = _alike_but_not_as_tall(tracker, np.random.default_rng(21), 1.75, 0.2)
    assert back == before
    tracker = identity_tracker(visit_rate=0.01)
    before, back = _alike_but_not_as_tall(tracker, np.random.default_rng(21), 1.75, 0.2)
    assert back != before


def test_someone_of_another_height_does_not_take_a_pooled_identity() -> None:
    before, back = _alike_but_not_as_tall(identity_tracker(), np.random.default_rng(22), 1.62)
    assert back != before


def test_a_stranger_does_not_take_a_pooled_identity() -> None:
    rng = np.random.default_rng(6)
    tracker = identity_tracker()
    out, t = _warm_up(tracker, rng)
    old = {tr.stable_id for tr in out.tracks}
    out = _leave_and_return(tracker, rng, t, 1000, colour=15)  # not the one who left
    back = [tr for tr in out.tracks if tr.x > 5.0]
    assert len(back) == 1
    assert back[0].stable_id not in old
    assert back[0].stable_id == back[0].id


def test_a_new_track_begun_before_the_old_one_was_given_up_takes_back_its_identity() -> None:
    """The person in colour 4 is next seen 2.5 m from where their track expects them: a
    new track starts while the old one still waits for them. When the old one is given
    up, the new one is among the people alive with it, the most alike of them; it is not
    its own impostor, and takes the identity back."""
    rng = np.random.default_rng(12)
    tracker = identity_tracker()
    out, t = _warm_up(tracker, rng)
    before = {round(tr.y): tr.stable_id for tr in out.tracks}
    for j in range(int(10.0 / FRAME)):
        tt = t + j * FRAME
        dets = [walker(i, tt, look(3 * i + 1, rng)) for i in (0, 2)]
        dets.append(person(4.5 + 0.01 * j, 4.5, look(4, rng), u=700))
        out = tracker.step(batch(tt, tuple(dets), 2000 + j))
    moved = [tr for tr in out.tracks if tr.x > 4.0]
    assert len(moved) == 1 and moved[0].id != before[4]  # a new track...
    assert moved[0].stable_id == before[4]  # ...with the old identity
    assert tracker.identity.counters["reidentified"] == 1


def test_a_pooled_identity_is_only_taken_where_its_person_could_have_walked() -> None:
    rng = np.random.default_rng(7)
    tracker = identity_tracker(reid_max_speed_mps=0.05, reid_margin_m=0.5)
    out, t = _warm_up(tracker, rng)
    out = _leave_and_return(tracker, rng, t, 1000, colour=4, where=(9.0, 9.0), gone_s=10.0)
    back = [tr for tr in out.tracks if tr.x > 5.0]
    assert back[0].stable_id == back[0].id


def test_the_pool_forgets_after_pool_s() -> None:
    rng = np.random.default_rng(8)
    tracker = identity_tracker(pool_s=5.0)
    out, t = _warm_up(tracker, rng)
    out = _leave_and_return(tracker, rng, t, 1000, colour=4, gone_s=20.0)
    back = [tr for tr in out.tracks if tr.x > 5.0]
    assert back[0].stable_id == back[0].id


def test_stable_ids_are_never_on_two_tracks_at_once() -> None:
    rng = np.random.default_rng(9)
    tracker = identity_tracker()
    out, t = _warm_up(tracker, rng)
    for rep in range(3):
        out = _leave_and_return(tracker, rng, t + rep * 40.0, 1000 + rep * 1000, colour=4)
        stable = [tr.stable_id for tr in out.tracks]
        assert len(stable) == len(set(stable))


# -------------------------------------------------------------------- the roster


def _roster_of(tracker) -> Roster:
    entries = []
    for tid, name in ((1, "ada"), (2, "bo"), (3, "cy")):
        looks = tracker.identity.looks_of(tid)
        entries.append(
            RosterEntry(name, tuple(looks.signature.tolist()), (), int(looks.observations))
        )
    return Roster(tuple(entries))


def test_registered_people_are_named_one_to_one() -> None:
    rng = np.random.default_rng(10)
    tracker = identity_tracker()
    _warm_up(tracker, rng)
    roster = _roster_of(tracker)
    fresh = identity_tracker()
    fresh.identity.set_roster(roster)
    names_seen = []
    out, t = _warm_up(fresh, rng, frames=120)
    for k in range(120):
        dets = tuple(person(1.0, 2.0 + 2.5 * i, look(3 * i + 1, rng)) for i in range(3))
        out = fresh.step(batch(t + k * FRAME, dets, 5000 + k))
        names = [tr.identity for tr in out.tracks if tr.identity]
        assert len(names) == len(set(names))
        names_seen.append({round(tr.y): tr.identity for tr in out.tracks})
    assert names_seen[-1] == {2: "ada", 4: "bo", 7: "cy"}


def test_a_lookalike_in_the_roster_leaves_the_track_unnamed_not_named_by_a_coin_toss() -> None:
    rng = np.random.default_rng(11)
    tracker = identity_tracker()
    _warm_up(tracker, rng)
    roster = _roster_of(tracker)
    ada, bo, cy = roster.people
    twin = replace(ada, name="ada's twin")
    # dressed nearly like bo: evidence for both names grows, bo's a little faster
    mix = 0.95 * np.array(bo.signature) + 0.05 * np.array(cy.signature)
    cousin = replace(bo, name="bo's cousin", signature=tuple(mix.tolist()))
    fresh = identity_tracker()
    fresh.identity.set_roster(Roster((ada, bo, cy, twin, cousin)))
    out, _ = _warm_up(fresh, rng, frames=600)
    # long enough for the evidence to reach its bound: bo's margin over the cousin
    # must survive it (clipping both names at the bound erased it)
    assert {round(tr.y): tr.identity for tr in out.tracks} == {2: None, 4: "bo", 7: "cy"}


def _dressed_alike_named(height_weight: float) -> dict[int, str | None]:
    """Three people in one uniform, 1.55, 1.75 and 1.95 m tall, registered from their
    own tracks, then seen by a fresh tracker: the names it gives, by row."""
    heights = (1.55, 1.75, 1.95)

    def walk(tracker, rng, frames):
        for k in range(frames):
            t = T0 + k * FRAME
            dets = tuple(
                walker(i, t, look(7, rng), height=heights[i] + rng.normal(0.0, 0.02))
                for i in range(3)
            )  # fmt: skip
            out = tracker.step(batch(t, dets, k))
        return out

    rng = np.random.default_rng(13)
    tracker = identity_tracker(height_weight=height_weight)
    out = walk(tracker, rng, 300)
    enough = tracker.identity.cfg.min_observations
    roster = Roster(
        tuple(
            entry_from_looks(f"p{round(tr.y)}", tracker.identity.looks_of(tr.id), enough)
            for tr in out.tracks
        )
    )  # fmt: skip
    fresh = identity_tracker(height_weight=height_weight)
    fresh.identity.set_roster(roster)
    return {round(tr.y): tr.identity for tr in walk(fresh, rng, 600).tracks}


def test_registered_heights_tell_apart_people_dressed_alike() -> None:
    assert _dressed_alike_named(1.0) == {2: "p2", 4: "p4", 7: "p7"}
    # colours alone: three registered look-alikes, nobody named by a coin toss
    assert _dressed_alike_named(0.0) == {2: None, 4: None, 7: None}


def test_lookalikes_registered_from_their_own_tracks_keep_their_names(tmp_path: Path) -> None:
    rng = np.random.default_rng(12)
    tracker = identity_tracker()
    _warm_up(tracker, rng)
    keeper = RosterKeeper(tmp_path / "roster.yaml")
    uniform = 7  # ada and her twin dress alike (bo and cy are as before)

    def step(t: float, k: int):
        dets = tuple(walker(i, t, look(c, rng)) for i, c in enumerate((uniform, 4, uniform)))
        return tracker.step(batch(t, dets, k))

    t0 = T0 + 300 * FRAME
    for k in range(300):  # the tracks learn their new looks
        out = step(t0 + k * FRAME, 300 + k)
    by_y = {round(tr.y): tr.id for tr in out.tracks}
    keeper.request(tracker.identity, roster_request("add", "ada", by_y[2]))
    keeper.request(tracker.identity, roster_request("add", "twin", by_y[7]))
    for k in range(600, 900):
        out = step(T0 + k * FRAME, k)
        names = {round(tr.y): tr.identity for tr in out.tracks}
        assert names[2] == "ada" and names[7] == "twin"


def test_roster_file_roundtrip_and_errors(tmp_path: Path) -> None:
    path = tmp_path / "roster.yaml"
    roster = Roster((RosterEntry("Ada Lovelace", (0.5, 0.5), (), 12, "2026-11-24T10:00:00Z"),))
    save_roster(roster, path)
    assert load_roster(path) == roster
    assert load_roster(tmp_path / "missing.yaml") == Roster()
    path.write_text("version: 1\npeople:\n  - name: x\n    colour: [1]\n")
    with pytest.raises(ConfigError, match=r"people\[0\]: unknown key 'colour'"):
        load_roster(path)
    path.write_text("version: 1\npeople:\n  - name: ''\n    signature: [1]\n")
    with pytest.raises(ConfigError, match=r"people\[0\]\.name"):
        load_roster(path)
    path.write_text(
        "version: 1\npeople:\n  - {name: a, signature: [1]}\n  - {name: a, signature: [1]}\n"
    )
    with pytest.raises(ConfigError, match="registered twice"):
        load_roster(path)
    path.write_text("version: 1\npeople:\n  - {name: a, signature: [.nan]}\n")
    with pytest.raises(ConfigError, match="finite"):
        load_roster(path)
    path.write_text("version: 1\npeople:\n  - {name: a, signature: [1], height: 25}\n")
    with pytest.raises(ConfigError, match=r"people\[0\]\.height: expected metres from 0.5"):
        load_roster(path)
    path.write_text("version: 1\npeople:\n  - {name: a, signature: [1], height: null}\n")
    assert load_roster(path).people[0].height == 0.0
    tall = Roster((RosterEntry("Bo", (1.0,), height=1.82),))
    save_roster(tall, path)
    assert load_roster(path) == tall and "height: 1.82" in path.read_text()


# ------------------------------------------------------------- replay, checkpoint


def test_identity_state_survives_a_late_batch_replay() -> None:
    rng = np.random.default_rng(11)
    items = []
    for k in range(400):
        t = T0 + k * FRAME
        for s, sensor in enumerate(("a", "b")):
            dets = tuple(
                person(1.0 + 0.5 * i + 0.1 * s, 2.0 + 2.5 * i, look(3 * i + 1, rng))
                for i in range(3)
            )
            items.append(batch(t + 0.001 * s, dets, k, sensor))
    late = items.pop(301)  # sensor b's frame 150 arrives 0.3 s late
    late_order = items[:]
    late_order.insert(301 + 18, late)
    ontime_order = sorted(late_order, key=lambda b: b.stamp)
    results = []
    for order in (late_order, ontime_order):
        tracker = identity_tracker()
        for b in order:
            tracker.step(b)
        results.append(tracker)
    a, b = (r.identity for r in results)
    assert results[0].counters["late_applied"] == 1
    np.testing.assert_array_equal(a.models.sig, b.models.sig)
    np.testing.assert_array_equal(a.colour.counts, b.colour.counts)


def test_identity_is_part_of_the_checkpoint(tmp_path: Path) -> None:
    from openptrack_py.tracking.checkpoint import CheckpointStore

    rng = np.random.default_rng(12)
    tracker = identity_tracker()
    _warm_up(tracker, rng)
    tracker.identity.counters["reidentified"] = 0
    store = CheckpointStore(tmp_path / "tracker.ckpt")
    store.save(tracker)
    restarted = identity_tracker()
    checkpoint = store.load()
    restarted.restore_state(checkpoint.table, checkpoint.time, checkpoint.roles)
    np.testing.assert_array_equal(restarted.identity.models.sig, tracker.identity.models.sig)
    assert restarted.identity.colour.ready


def test_a_checkpoint_from_before_heights_restores_without_them() -> None:
    import pickle

    rng = np.random.default_rng(14)
    tracker = identity_tracker()
    _warm_up(tracker, rng)
    old = tracker.identity.snapshot()
    models = old[0]
    for name in ("hgt", "hgt_n", "visit"):  # as an older version wrote them
        del models.__dict__[name]
    restarted = identity_tracker()
    restarted.identity.restore(pickle.loads(pickle.dumps(old[:10])))
    m = restarted.identity.models
    assert m.hgt.shape == m.hgt_n.shape == (len(m),) and not m.hgt_n.any()
    np.testing.assert_array_equal(m.visit, m.sig)  # the visit's colours start as the model
    assert not restarted.identity.stature.ready
    _warm_up(restarted, rng, frames=60, k0=300, t0=T0 + 300 * FRAME)  # and it runs on
    assert restarted.identity.models.hgt_n.max() > 0


def test_return_evidence_from_before_faces_were_averaged_apart_still_counts() -> None:
    """Checkpoints written before faces were averaged apart hold (sum, observations)."""
    tracker = identity_tracker()
    old = list(tracker.identity.snapshot())
    old[3] = {7: {2: (30.0, 15.0)}}  # a young track's evidence, as an older version wrote it
    restarted = identity_tracker()
    restarted.identity.restore(tuple(old))
    assert restarted.identity.reid_ev == {7: {2: (30.0, 15.0, 0.0, 0.0)}}


def test_identity_off_is_the_default_and_costs_nothing() -> None:
    tracker = build_tracker()
    assert not tracker.identity.needs_looks
    assert not isinstance(tracker.identity, AppearanceIdentity)


def test_colours_keep_two_people_apart_where_motion_would_swap_them() -> None:
    """They meet and turn back: motion predicts they pass; colours say they did not."""
    rng = np.random.default_rng(13)
    tracker = identity_tracker()
    _, t = _warm_up(tracker, rng)
    for rep in range(3):
        t0 = t + 2.0 + rep * 6.0
        # first, each one's identity while they stand apart
        out = None
        for k in range(60):
            w = 0.3 * math.sin(k / 10)
            dets = (
                person(3.8, 8.0 + w, look(2, rng), u=300),
                person(6.2, 8.0 - w, look(11, rng), u=600),
            )
            out = tracker.step(batch(t0 - 2.0 + k * FRAME, dets, 1500 + rep * 300 + k))
        left = {tr.stable_id for tr in out.tracks if 3.0 < tr.x < 4.5 and tr.y > 7}
        right = {tr.stable_id for tr in out.tracks if 5.5 < tr.x < 7.0 and tr.y > 7}
        ids_after = _crossing(tracker, rng, t0, 1600 + rep * 300)
        assert ids_after[0] == left
        assert ids_after[1] == right


def _blob_scene(tracker, rng, t0, k0):
    """Two people stand apart, walk up to each other and stand as one blob for 5 s, part.

    Returns the stable ids on each side before, the ids published during the blob, and
    the stable ids on each side after.
    """
    during: list[set] = []
    ids_before: dict = {}
    out = None
    k = k0
    # frames and half separation at the start and end of each phase (0: one blob)
    phases = ((90, 1.2, 1.2), (30, 1.2, 0.3), (150, 0.0, 0.0), (30, 0.3, 1.2), (30, 1.2, 1.2))
    for p, (frames, h0, h1) in enumerate(phases):
        for j in range(frames):
            t = t0 + (k - k0) * FRAME
            half = h0 + (h1 - h0) * j / frames
            if half:
                w = 0.4 * math.sin(j / 8) if p == 0 else 0.0
                dets = (
                    person(5.0 - half + w, 11.0, look(2, rng), u=300),
                    person(5.0 + half - w, 11.0, look(11, rng), u=600),
                )
            else:  # one blob: both people's colours, at their centroid
                mixed = tuple((np.array(look(2, rng)) + np.array(look(11, rng))) // 2)
                dets = (person(5.0 + 0.05 * math.sin(j / 5), 11.0, mixed, u=450),)
            out = tracker.step(batch(t, dets, k))
            k += 1
            if p == 2:
                during.append({tr.stable_id for tr in out.tracks if tr.y > 10})
        if p == 0:
            ids_before = {tr.x < 5.0: tr.stable_id for tr in out.tracks if tr.y > 10}
    after = {tr.x < 5.0: tr.stable_id for tr in out.tracks if tr.y > 10}
    return ids_before, during, after


def test_two_people_in_one_blob_keep_both_identities() -> None:
    rng = np.random.default_rng(14)
    tracker = identity_tracker()
    _, t = _warm_up(tracker, rng, frames=400)
    before, during, after = _blob_scene(tracker, rng, t + 1.0, 3000)
    assert len(before) == 2
    assert all(ids == set(before.values()) for ids in during[30:])  # both stay published
    assert after == before  # and each is on their own side when they part


def _face(k: int, rng: np.random.Generator, noise: float = 0.1) -> tuple[float, ...]:
    base = np.random.default_rng(100 + k).normal(size=16)
    v = base / np.linalg.norm(base) + rng.normal(0, noise, 16)
    return tuple((v / np.linalg.norm(v)).tolist())


def _back_in_uniform(face_every: int) -> tuple[int, int]:
    """Three people in one uniform, each face seen; the middle one leaves for 20 s and
    comes back, their face seen in one frame of ``face_every``. Returns the middle one's
    stable id before and the returning track's."""
    rng = np.random.default_rng(15)
    tracker = identity_tracker()
    uniform = look(5, rng)
    t = T0
    for k in range(300):
        t = T0 + k * FRAME
        dets = tuple(
            replace(
                person(1.0 + 0.3 * math.sin(t - T0 + i), 2.0 + 2.5 * i, uniform),
                face=_face(i, rng),
                face_confidence=0.8,
            )
            for i in range(3)
        )
        out = tracker.step(batch(t, dets, k))
    before = {round(tr.y): tr.stable_id for tr in out.tracks}
    assert tracker.identity.face.ready
    k0 = 1000
    for j in range(int(20 / (5 * FRAME))):  # person 1 away for 20 s
        dets = tuple(
            replace(person(1.0, 2.0 + 2.5 * i, uniform), face=_face(i, rng), face_confidence=0.8)
            for i in (0, 2)
        )
        out = tracker.step(batch(t + (j + 1) * 5 * FRAME, dets, k0 + j))
    t = out.stamp
    for j in range(120):
        dets = tuple(
            replace(person(1.0, 2.0 + 2.5 * i, uniform), face=_face(i, rng), face_confidence=0.8)
            for i in (0, 2)
        )
        face = _face(1, rng) if j % face_every == 0 else None
        dets += (replace(person(6.0 + 0.01 * j, 6.0, uniform, u=700), face=face),)
        out = tracker.step(batch(t + (j + 1) * FRAME, dets, 5000 + j))
    back = [tr for tr in out.tracks if tr.x > 5.0]
    assert len(back) == 1
    return before[4], back[0].stable_id


def test_identity_embeddings_alone_reidentify_people_who_dress_alike() -> None:
    before, back = _back_in_uniform(face_every=1)
    assert back == before


def test_a_face_seen_in_few_frames_counts_as_much_as_in_all() -> None:
    """Faces and colours are each averaged over the frames that carry them: a face seen
    in one frame of five is not diluted by the four with colours that say nothing."""
    before, back = _back_in_uniform(face_every=5)
    assert back == before


def _walk_out_together_then_someone_comes_in(tracker, rng, t0, k0):
    """Two people walk side by side out at x = 9, nothing is seen for 2 s, and a third
    person comes in through the same place, in colours as like the two together as a
    blob of them would be (where many dress alike, somebody does). Returns the tracks
    near the newcomer during its last second."""
    k, out = k0, None
    for j in range(150):  # side by side, detected as two, walking out
        t = t0 + j * FRAME
        x, half = 5.0 + 0.03 * j, 0.5 if j < 100 else 0.25  # closing up at the door
        dets = (
            person(x, 11.0 - half, look(2, rng), u=300),
            person(x, 11.0 + half, look(11, rng), u=600),
        )
        out = tracker.step(batch(t, dets, k))
        k += 1
    t0 = t0 + 150 * FRAME + 2.0  # gone; nothing seen for 2 s
    near = []
    for j in range(150):  # the next person comes in where they left
        t = t0 + j * FRAME
        mixed = tuple((np.array(look(2, rng)) + np.array(look(11, rng))) // 2)
        out = tracker.step(batch(t, (person(9.5 - 0.03 * j, 11.0, mixed, u=450),), k))
        k += 1
        if j >= 120:
            x = 9.5 - 0.03 * j
            near.append({tr.id for tr in out.tracks if abs(tr.x - x) < 1.0 and tr.y > 10})
    return near


def test_two_people_who_walk_out_together_do_not_haunt_the_next_one_in() -> None:
    rng = np.random.default_rng(21)
    tracker = identity_tracker()
    _, t = _warm_up(tracker, rng, frames=400)
    near = _walk_out_together_then_someone_comes_in(tracker, rng, t + 1.0, 5000)
    assert all(len(ids) <= 1 for ids in near), near  # no ghost shares the newcomer


def test_the_return_rate_is_learned_from_the_evidence() -> None:
    """EM recovers the share of returns from calibrated likelihood ratios (an oracle)."""
    rng = np.random.default_rng(3)
    for true_rate in (0.1, 0.5, 0.9):
        est = ReturnRate(memory=400)
        for _ in range(400):
            n = 8
            # a calibrated log-likelihood ratio: N(+2, 2) for the same person, N(-2, 2)
            # for someone else (the ratio of the two densities is exp(2 x))
            llr = 2.0 * rng.normal(-1.0, 1.0, n)
            if rng.random() < true_rate:
                llr[0] = 2.0 * rng.normal(1.0, 1.0)
            est.add(llr)
        assert abs(est.rate - true_rate) < 0.1, (true_rate, est.rate)


def test_a_link_needs_more_evidence_among_more_look_alikes_and_rarer_returns() -> None:
    one = link_posterior(np.array([[2.0, -np.inf, -np.inf]]), 0.5)
    many = link_posterior(np.array([[2.0, 0.0, 0.0]]), 0.5)
    rare = link_posterior(np.array([[2.0, -np.inf, -np.inf]]), 0.1)
    assert one[0, 0] > many[0, 0] and one[0, 0] > rare[0, 0]
    assert one[0, 1] == 0.0  # out of reach
    both = link_posterior(np.array([[3.0, 3.0], [-1.0, 0.5]]), 0.7)
    assert (both.sum(axis=1) <= 1.0).all()


def test_names_survive_a_late_batch_replay_from_before_the_roster_changed(
    tmp_path: Path,
) -> None:
    """A batch arriving late just after ``roster add`` replays from a snapshot taken
    before it: the name said by hand must be said again, and the evidence follow the
    roster by name (it was zeroed, and the lookalikes left unnamed for good)."""
    rng = np.random.default_rng(12)
    tracker = identity_tracker()
    _warm_up(tracker, rng)
    keeper = RosterKeeper(tmp_path / "roster.yaml")

    def dets(t: float) -> tuple[Detection, ...]:
        # the first and the last dress alike
        return tuple(walker(i, t, look(c, rng)) for i, c in enumerate((7, 4, 7)))

    for k in range(300, 600):
        out = tracker.step(batch(T0 + k * FRAME, dets(T0 + k * FRAME), k))
    by_y = {round(tr.y): tr.id for tr in out.tracks}
    keeper.request(tracker.identity, roster_request("add", "ada", by_y[2]))
    keeper.request(tracker.identity, roster_request("add", "twin", by_y[7]))
    late = T0 + 590.5 * FRAME  # another sensor's frame from before the requests
    tracker.step(batch(late, dets(late), 0, sensor="s1"))
    assert tracker.counters["late_applied"] == 1
    for k in range(600, 700):
        out = tracker.step(batch(T0 + k * FRAME, dets(T0 + k * FRAME), k))
        names = {round(tr.y): tr.identity for tr in out.tracks}
        assert names[2] == "ada" and names[7] == "twin"


def test_a_replay_after_a_roster_change_keeps_every_name_column_in_step() -> None:
    """Pooled identities from a snapshot taken under the old roster follow it by name
    (their evidence kept the old width, which a link cannot combine with a track's)."""
    rng = np.random.default_rng(13)
    tracker = identity_tracker()
    _warm_up(tracker, rng)
    identity = tracker.identity
    lost = PooledIdentity(
        stable=99, sig=np.zeros(BINS), sig_n=0.0, emb=np.zeros(0), emb_w=0.0,
        xy=np.zeros(2), lost_at=T0, name_ev=np.zeros(0),
    )  # fmt: skip
    identity.pool += (lost,)
    before = identity.snapshot()
    identity.set_roster(_roster_of(tracker))
    identity.restore(before)
    assert identity.models.name_ev.shape[1] == 3
    assert [len(e.name_ev) for e in identity.pool] == [3]


def _learn_two_floors(bias: HeightBias, rng, error_a, error_b, steps=200):
    """Sensors a and b see the same 30 people (1.5-1.9 m) walking around, each from its
    own tilted floor; returns the people's positions and heights of the last step."""
    tall = rng.uniform(1.5, 1.9, 30)
    for k in range(steps):
        t = T0 + k * FRAME
        xy = rng.uniform(0.0, 6.0, (30, 2))
        for sensor, error in (("a", error_a), ("b", error_b)):
            seen = tall + error(xy) + rng.normal(0.0, 0.03, 30)
            bias.learn(sensor, np.arange(30), xy, seen, t + (sensor == "b") * 0.01)
    return xy, tall


def test_each_sensors_height_error_is_learned_as_a_plane() -> None:
    """Against the other sensor's heights of the same people, not against the people's
    models (which hold each sensor's own heights too, and hide part of its error)."""
    rng = np.random.default_rng(23)
    bias = HeightBias()
    xy = rng.uniform(0.0, 6.0, (5, 2))
    assert (bias.correct("a", xy, np.full(5, 1.7)) == 1.7).all()  # nothing learned

    def a(xy):  # a floor tilted by about 0.6 degree
        return 0.04 + 0.01 * xy[:, 0] - 0.005 * xy[:, 1]

    def b(xy):
        return -a(xy)

    xy, tall = _learn_two_floors(bias, rng, a, b)
    for sensor, error in (("a", a), ("b", b)):
        fixed = bias.correct(sensor, xy, tall + error(xy))
        assert np.abs(fixed - tall).max() < 0.01
    assert (bias.correct("c", xy, tall) == tall).all()  # per sensor


def test_what_every_sensor_shares_is_not_taken_for_an_error() -> None:
    """Both floors 5 cm high: nothing tells it from everyone being 5 cm taller, and the
    corrections, which only remove the sensors' differences, stay at 0 (not drifting)."""
    rng = np.random.default_rng(25)
    bias = HeightBias()

    def high(xy):
        return np.full(len(xy), 0.05)

    xy, tall = _learn_two_floors(bias, rng, high, high, steps=400)
    for sensor in ("a", "b"):
        assert np.abs(bias.correct(sensor, xy, tall) - tall).max() < 0.005


def test_a_return_seen_by_another_sensor_than_the_leaving_is_recognised_by_height() -> None:
    """Two sensors measure everyone 12 cm apart; the person leaves under one, returns
    under the other, among people dressed alike: the tracker learns each sensor's
    error from the tracks they share, and heights still say who it is."""
    rng = np.random.default_rng(24)
    tracker = identity_tracker()
    heights, offset = (1.55, 1.75, 1.95), {"s0": 0.06, "s1": -0.06}

    def frame(t, k, sensor, who, extra=()):
        dets = tuple(
            walker(i, t, look(7, rng),
                   height=heights[i] + offset[sensor] + rng.normal(0.0, 0.02))
            for i in who
        ) + extra  # fmt: skip
        return tracker.step(batch(t, dets, k, sensor))

    for k in range(600):  # both sensors see everyone
        out = frame(T0 + k * FRAME / 2, k, ("s0", "s1")[k % 2], (0, 1, 2))
    before = min(out.tracks, key=lambda tr: abs(tr.y - 4.5)).stable_id
    where, bias = np.array([[1.5, 4.5]]), tracker.identity.height_bias
    seen = [bias.correct(s, where, np.array([1.75 + offset[s]]))[0] for s in ("s0", "s1")]
    assert abs(seen[0] - seen[1]) < 0.02
    for k in range(300):  # the middle one leaves (last seen by s0 alone), 20 s away
        out = frame(T0 + 300 * FRAME + k * 4 * FRAME, 600 + k, "s0", (0, 2))
    t = T0 + 1500 * FRAME
    for k in range(120):  # back, seen by s1 alone
        back = person(6.0 + 0.01 * k, 6.0, look(7, rng), u=700,
                      height=1.75 + offset["s1"] + rng.normal(0.0, 0.02))  # fmt: skip
        out = frame(t + k * FRAME, 900 + k, "s1", (0, 2), (back,))
    assert next(tr.stable_id for tr in out.tracks if tr.x > 5.0) == before


def test_the_pools_evidence_means_are_each_pairs_mean() -> None:
    """:meth:`ReidPool._means` (per candidate, vectorised) against :func:`mean_evidence`
    of every pair, with an identity pooled twice and evidence for identities no longer
    pooled."""
    from types import SimpleNamespace

    from openptrack_py.tracking.identity.reid import ReidPool, mean_evidence

    rng = np.random.default_rng(3)
    pool = ReidPool.__new__(ReidPool)
    pool.pool = tuple(SimpleNamespace(stable=s) for s in (9, 4, 17, 4, 30))
    pool.reid_ev = {}
    for tid in (101, 102, 103):
        keys = rng.choice([4, 9, 17, 30, 55, 60], size=rng.integers(0, 6), replace=False)
        pool.reid_ev[tid] = {
            int(s): (
                float(rng.normal()), float(rng.integers(0, 20)),
                float(rng.normal()), float(rng.choice([0.0, 5.0, 12.5])),
            )
            for s in keys
        }  # fmt: skip
    cands = [101, 102, 103]
    expected = [[mean_evidence(pool.reid_ev[c].get(e.stable)) for e in pool.pool] for c in cands]
    assert pool._means(cands).tolist() == expected
