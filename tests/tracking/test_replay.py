"""Late batches: replayed exactly from a snapshot, or dropped, never a crash."""

from __future__ import annotations

import copy
from collections.abc import Sequence

import numpy as np
import pytest

from openptrack_py.config import TrackerConfig
from openptrack_py.messages.detection import DetectionBatch
from openptrack_py.messages.track import TrackBatch
from openptrack_py.tracking import (
    Tracker,
    TrackingPipeline,
    build_tracker,
)
from tests.tracking.helpers import (
    FRAME,
    T0,
    det,
    is_spd,
    make_batch,
)

# ---------------------------------------------------------- late batches


def _walker_stream(
    seed: int, late_seq: int = 30, offset: tuple[float, float] = (0.0, 0.15), late_by: float = 0.2
) -> tuple[list[tuple[DetectionBatch, float]], tuple[DetectionBatch, float]]:
    """Two 30 Hz sensors see one walker; sensor b's frame ``late_seq`` arrives late.

    That frame's detection is displaced by ``offset`` so that its effect is visible.
    Returns ``(batch, arrival)`` pairs in arrival order, and the late pair.
    """
    rng = np.random.default_rng(seed)
    items = []
    late = None
    for k in range(60):
        for sensor, phase in (("a", 0.0), ("b", 0.016)):
            stamp = T0 + k * FRAME + phase
            xy = np.array([2.0, 2.0]) + (stamp - T0) * np.array([1.0, 0.3])
            xy += rng.normal(0, 0.03, 2)
            arrival = stamp + 0.01
            if sensor == "b" and k == late_seq:
                xy += offset
                arrival += late_by + 0.003  # no tie with the batch captured late_by later
            item = (make_batch(stamp, [det(*xy, distance=2.0)], sensor=sensor, seq=k), arrival)
            items.append(item)
            if sensor == "b" and k == late_seq:
                late = item
    assert late is not None
    items.sort(key=lambda item: item[1])
    return items, late


def _run_until(
    items: Sequence[tuple[DetectionBatch, float]],
    until: float,
    policy: str = "replay",
    by_stamp: bool = False,
    skip: DetectionBatch | None = None,
) -> TrackingPipeline:
    """Feed every batch arriving by ``until`` (or, ``by_stamp``, captured by it, on time)."""
    cfg = TrackerConfig(late_policy=policy)  # type: ignore[arg-type]
    pipe = TrackingPipeline(
        build_tracker(cfg), window_s=cfg.reorder_window_s, clock_correction="none"
    )
    ordered = sorted(items, key=lambda item: item[0].stamp) if by_stamp else items
    for batch, arrival in ordered:
        if (batch.stamp if by_stamp else arrival) > until + 1e-9 or batch is skip:
            continue
        pipe.push(batch, batch.stamp + 0.01 if by_stamp else arrival)
    pipe.flush()
    return pipe


def _same_state(a: Tracker, b: Tracker) -> None:
    assert a.time == b.time and a.max_id == b.max_id
    np.testing.assert_array_equal(a.table.ids, b.table.ids)
    np.testing.assert_allclose(a.table.x, b.table.x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.table.cov, b.table.cov, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(a.table.hits, b.table.hits)


def test_late_batch_is_replayed_exactly() -> None:
    items, (late, arrival) = _walker_stream(0)
    pipe = _run_until(items, arrival)
    tracker = pipe.tracker
    assert pipe.late == 1
    assert tracker.counters["late_applied"] == 1
    assert tracker.counters["late_dropped"] == 0
    assert tracker.counters["replayed_steps"] >= 1
    assert tracker.counters["tracks_started"] == 1
    assert tracker.time == pytest.approx(late.stamp + 0.2, abs=0.02)
    assert tracker.table.last_seen[0] == tracker.time  # the late stamp does not rewind it
    assert is_spd(tracker.table.cov)
    on_time = _run_until(items, tracker.time, by_stamp=True).tracker  # same batches, in order
    assert on_time.counters["late_applied"] == 0
    _same_state(tracker, on_time)
    # it was really used: dropping it gives another state
    dropped = _run_until(items, arrival, "drop").tracker
    assert not np.array_equal(tracker.table.x, dropped.table.x)
    assert np.linalg.det(tracker.table.cov[0]) < np.linalg.det(dropped.table.cov[0])


@pytest.mark.parametrize("seed", range(4), ids=lambda s: f"seed{s}")
def test_late_displaced_detection_gives_the_on_time_result(seed: int) -> None:
    items, (_, arrival) = _walker_stream(seed, offset=(0.0, 0.15))
    replayed = _run_until(items, arrival).tracker
    drop = _run_until(items, arrival, "drop").tracker
    on_time = _run_until(items, replayed.time, by_stamp=True).tracker
    # the on-time answer moves the position towards the displaced late detection...
    assert on_time.table.x[0, 1] > drop.table.x[0, 1]
    # ...and the replay gives exactly that answer
    _same_state(replayed, on_time)


def test_late_batch_is_dropped_with_drop_policy() -> None:
    items, (late, arrival) = _walker_stream(1)
    pipe = _run_until(items, arrival, "drop")
    tracker = pipe.tracker
    assert pipe.late == 1
    assert tracker.counters["late_dropped"] == 1
    assert tracker.counters["late_applied"] == 0
    without = _run_until(items, arrival, "drop", skip=late).tracker
    np.testing.assert_array_equal(tracker.table.x, without.table.x)
    np.testing.assert_array_equal(tracker.table.cov, without.table.cov)
    np.testing.assert_array_equal(tracker.table.hits, without.table.hits)


@pytest.mark.parametrize("policy", ["replay", "drop"], ids=["replay", "drop"])
def test_late_batches_are_replayed_or_dropped_never_crash(policy: str) -> None:
    cfg = TrackerConfig(late_policy=policy)  # type: ignore[arg-type]
    fed: list[DetectionBatch] = []
    tracker = build_tracker(cfg)

    def feed(batch: DetectionBatch) -> TrackBatch:
        fed.append(batch)
        return tracker.step(batch)

    feed(make_batch(T0 + 1.0))  # empty tracker, clock at T0 + 1
    out = feed(make_batch(T0 + 0.8, [det(2.0, 2.0, conf=0.3)]))  # late and weak
    assert out.alive_ids == ()
    last = T0 + 1.1
    for k in range(4):
        last = T0 + 1.1 + k * FRAME
        feed(make_batch(last, [det(2.0, 2.0)], seq=k))
    before = copy.deepcopy(tracker)
    feed(make_batch(last - 0.2, [det(6.0, 6.0, conf=0.95)], seq=80))  # late: a new person
    out = feed(make_batch(last - 0.1, seq=81))  # late and empty
    late_key = "late_applied" if policy == "replay" else "late_dropped"
    assert tracker.counters[late_key] == 3
    if policy == "drop":
        _same_state(tracker, before)
    else:
        # exactly the state the same batches give in capture order
        reference = build_tracker(cfg)
        for batch in sorted(fed, key=lambda b: b.stamp):
            reference.step(batch)
        _same_state(tracker, reference)
        assert tracker.counters["replayed_steps"] > 0
    assert 1 in tracker.table.ids
    # beyond max_lateness_s a batch is always dropped
    dropped = tracker.counters["late_dropped"]
    snapshot = copy.deepcopy(tracker)
    tracker.step(make_batch(last - cfg.max_lateness_s - 0.1, [det(2.0, 2.0)], seq=82))
    assert tracker.counters["late_dropped"] == dropped + 1
    _same_state(tracker, snapshot)
