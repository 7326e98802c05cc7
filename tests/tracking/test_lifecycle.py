"""Track lifecycle: initiation, confirmation, deletion, publication."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from openptrack_py.config import TrackerConfig
from openptrack_py.messages.detection import DetectionBatch
from openptrack_py.messages.track import TrackBatch
from openptrack_py.tracking import (
    Tracker,
    build_tracker,
)
from tests.tracking.helpers import (
    FRAME,
    T0,
    det,
    feed_still,
    make_batch,
)

# These tests feed people standing still: they check the lifecycle rules, not that a
# track must have moved before it is confirmed (tested below on its own).
STILL = {"confirm_min_displacement_m": 0.0, "confirm_min_age_s": 0.0}


# ------------------------------------------------------------- lifecycle


def _kept(tracker: Tracker, batch: DetectionBatch) -> list[int]:
    """The ids the tracker keeps (published or not) after a step."""
    tracker.step(batch)
    return tracker.table.ids.tolist()


def test_tentative_tracks_are_not_published_by_default() -> None:
    tracker = build_tracker(TrackerConfig(**STILL))
    out = tracker.step(make_batch(T0, [det(2.0, 2.0)]))
    assert out.tracks == ()
    assert out.alive_ids == ()  # heartbeats never list an id no frame showed
    assert out.max_id == 0


def test_tentative_tracks_are_published_on_request() -> None:
    tracker = build_tracker(TrackerConfig(publish_tentative=True, **STILL))
    out = tracker.step(make_batch(T0, [det(2.0, 2.0)]))
    assert [(t.id, t.confirmed) for t in out.tracks] == [(1, False)]
    assert (out.tracks[0].x, out.tracks[0].y) == (2.0, 2.0)
    out = _step_still(tracker, 2, (2.0, 2.0))
    assert [(t.id, t.confirmed) for t in out.tracks] == [(1, True)]


def _step_still(
    tracker: Tracker, n: int, xy: tuple[float, float], conf: float = 0.9
) -> TrackBatch:
    assert tracker.time is not None
    out = None
    t = tracker.time
    for k in range(n):
        t += FRAME
        out = tracker.step(make_batch(t, [det(*xy, conf=conf)], seq=100 + k))
    assert out is not None
    return out


@pytest.mark.parametrize("n", [1, 3, 5], ids=["n1", "n3", "n5"])
def test_confirmation_after_detections_to_validate_confident_hits(n: int) -> None:
    tracker = build_tracker(TrackerConfig(detections_to_validate=n, **STILL))
    for k in range(n):
        out = tracker.step(make_batch(T0 + k * FRAME, [det(2.0, 2.0)], seq=k))
        assert [t.id for t in out.tracks] == ([1] if k == n - 1 else [])
        assert tracker.table.confirmed.tolist() == [k == n - 1]
    # low-confidence hits do not count towards confirmation
    tracker = build_tracker(TrackerConfig(detections_to_validate=n, **STILL))
    tracker.step(make_batch(T0, [det(2.0, 2.0)]))
    for k in range(1, 2 * n):
        tracker.step(make_batch(T0 + k * FRAME, [det(2.0, 2.0, conf=0.3)], seq=k))
    assert tracker.table.hits.tolist() == [1]
    assert tracker.table.confirmed.tolist() == [n == 1]


def test_unconfirmed_track_is_deleted_after_sec_before_fake() -> None:
    cfg = TrackerConfig(
        sec_before_fake=1.5, detections_to_validate=3, tentative_timeout_s=10.0, **STILL
    )
    tracker = build_tracker(cfg)
    tracker.step(make_batch(T0, [det(2.0, 2.0)]))
    tracker.step(make_batch(T0 + 0.5, [det(2.0, 2.0)]))  # second hit, still tentative
    assert tracker.table.hits.tolist() == [2]
    assert _kept(tracker, make_batch(T0 + 1.45)) == [1]
    assert _kept(tracker, make_batch(T0 + 1.55)) == []
    assert tracker.counters["tracks_deleted"] == 1


def test_tentative_track_needs_its_hits_close_together() -> None:
    cfg = TrackerConfig(detections_to_validate=3, tentative_timeout_s=0.5, **STILL)
    tracker = build_tracker(cfg)
    tracker.step(make_batch(T0, [det(2.0, 2.0)]))
    tracker.step(make_batch(T0 + 0.4, [det(2.0, 2.0)]))  # second hit within the timeout
    assert _kept(tracker, make_batch(T0 + 0.85)) == [1]  # 0.45 s unseen: kept
    assert _kept(tracker, make_batch(T0 + 0.95)) == []  # 0.55 s unseen: gone
    # the same three hits 0.2 s apart confirm a track
    tracker = build_tracker(cfg)
    for k in range(3):
        tracker.step(make_batch(T0 + 0.2 * k, [det(2.0, 2.0)], seq=k))
    assert tracker.table.confirmed.tolist() == [True]


@pytest.mark.parametrize("old", [1.0, 3.0], ids=["1s", "3s"])
def test_confirmed_track_is_deleted_after_sec_before_old(old: float) -> None:
    tracker = build_tracker(TrackerConfig(sec_before_old=old, **STILL))
    last = feed_still(tracker, (2.0, 2.0), 4)
    assert tracker.table.confirmed.tolist() == [True]
    t = last
    while t + 0.1 < last + old - 0.05:
        t += 0.1
        assert _kept(tracker, make_batch(t)) == [1]
    assert _kept(tracker, make_batch(last + old - 0.02)) == [1]
    assert _kept(tracker, make_batch(last + old + 0.02)) == []


def test_unseen_confirmed_track_is_kept_but_not_published() -> None:
    tracker = build_tracker(TrackerConfig(publish_unseen_s=0.5, sec_before_old=3.0, **STILL))
    last = feed_still(tracker, (2.0, 2.0), 4)
    assert [t.id for t in tracker.step(make_batch(last + 0.4)).tracks] == [1]
    out = tracker.step(make_batch(last + 0.6))
    assert out.tracks == () and out.alive_ids == ()
    assert tracker.table.ids.tolist() == [1]  # kept, with its id
    out = tracker.step(make_batch(last + 1.5, [det(2.1, 2.0)]))  # seen again: same id
    assert [t.id for t in out.tracks] == [1]


def test_low_confidence_detections_update_but_do_not_keep_alive() -> None:
    cfg = TrackerConfig(sec_before_old=2.0, min_confidence_initialization=0.5, **STILL)
    tracker = build_tracker(cfg)
    last = feed_still(tracker, (2.0, 2.0), 4)
    hits = tracker.table.hits.tolist()
    x0 = tracker.table.x[0, 0]
    t = last
    weak = [det(2.2, 2.0, conf=0.3), det(6.0, 6.0, conf=0.45)]
    while t < last + cfg.visibility_timeout_s - FRAME:
        t += FRAME
        tracker.step(make_batch(t, weak))
    # while the track is being seen, weak detections refine it...
    moved = tracker.table.x[0, 0]
    assert moved > x0 + 0.05
    assert tracker.table.hits.tolist() == hits  # ...but do not count as hits
    assert tracker.table.last_seen.tolist() == [last]  # ...nor keep it alive
    # once it is lost, they no longer capture it: its uncertainty only grows
    t += 2 * FRAME
    tracker.step(make_batch(t, weak))
    sd = np.sqrt(tracker.table.cov[0, 0, 0])
    while t < last + 1.9:
        t += FRAME
        out = tracker.step(make_batch(t, weak))
    assert np.sqrt(tracker.table.cov[0, 0, 0]) > sd
    assert tracker.table.ids.tolist() == [1]
    assert tracker.counters["tracks_started"] == 1  # weak detections never start tracks
    while t < last + 2.1:
        t += FRAME
        out = tracker.step(make_batch(t, [det(2.2, 2.0, conf=0.3)]))
    assert tracker.table.ids.tolist() == [] and out.alive_ids == ()


def test_detections_below_min_confidence_detections_are_ignored() -> None:
    tracker = build_tracker(TrackerConfig(min_confidence_detections=0.2, **STILL))
    last = feed_still(tracker, (2.0, 2.0), 4)
    x0 = tracker.table.x.copy()
    probe = copy.deepcopy(tracker)
    tracker.step(make_batch(last, [det(2.2, 2.0, conf=0.1)]))
    np.testing.assert_array_equal(tracker.table.x, x0)
    probe.step(make_batch(last, [det(2.2, 2.0, conf=0.3)]))
    assert probe.table.x[0, 0] > x0[0, 0] + 0.01


@pytest.mark.parametrize("conf", [0.3, 0.9], ids=["weak-split", "confident-split"])
def test_second_blob_inside_the_gate_never_starts_a_track(conf: float) -> None:
    """A split blob (or a second sensor's duplicate) in the same batch as the person."""
    tracker = build_tracker(TrackerConfig(**STILL))
    last = feed_still(tracker, (2.0, 2.0), 4)
    tracker.step(make_batch(last + FRAME, [det(2.0, 2.0), det(2.15, 2.05, conf=conf)]))
    assert tracker.table.ids.tolist() == [1]
    assert tracker.counters["tracks_started"] == 1
    # the same blob outside every gate is someone else
    tracker.step(make_batch(last + 2 * FRAME, [det(2.0, 2.0), det(3.5, 2.0, conf=0.9)]))
    assert sorted(tracker.table.ids.tolist()) == [1, 2]


def test_ids_are_never_reused_and_alive_ids_are_the_published_ones() -> None:
    tracker = build_tracker(TrackerConfig(sec_before_old=1.0, sec_before_fake=1.0, **STILL))
    last = feed_still(tracker, (2.0, 2.0), 3)
    out = tracker.step(make_batch(last + FRAME, [det(2.0, 2.0), det(5.0, 5.0)]))
    assert [t.id for t in out.tracks] == [1]
    assert out.alive_ids == (1,)  # 2 is tentative: alive in the tracker, not shown
    assert out.max_id == 1
    out = tracker.step(make_batch(last + 2.0))  # both die
    assert out.alive_ids == ()
    assert out.max_id == 1
    out = tracker.step(make_batch(last + 2.1, [det(2.0, 2.0)]))  # same place, new person
    assert out.alive_ids == ()
    out = _step_still(tracker, 2, (2.0, 2.0))
    assert [t.id for t in out.tracks] == [3]  # 2 is never used again
    assert out.alive_ids == (3,) and out.max_id == 3


def test_track_fields_of_a_walker() -> None:
    tracker = build_tracker(TrackerConfig(**STILL))
    out = None
    for k in range(60):
        t = T0 + k * FRAME
        out = tracker.step(make_batch(t, [det(1.0 + 1.2 * (t - T0), 2.0)], seq=k))
    assert out is not None
    (track,) = out.tracks
    assert track.x == pytest.approx(1.0 + 1.2 * 59 * FRAME, abs=0.02)
    assert track.vx == pytest.approx(1.2, abs=0.05)
    assert track.vy == pytest.approx(0.0, abs=0.05)
    assert track.age == pytest.approx(59 * FRAME)
    assert 0.0 < track.confidence <= 1.0
    assert track.height == pytest.approx(1.75)
