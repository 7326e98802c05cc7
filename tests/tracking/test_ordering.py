"""Capture-time ordering: the reorder buffer and sensor clock alignment."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pytest

from openptrack_py.messages.detection import DetectionBatch
from openptrack_py.tracking import (
    ClockAligner,
    ReorderBuffer,
    TrackingPipeline,
    build_tracker,
)
from tests.tracking.helpers import (
    FRAME,
    T0,
    det,
    make_batch,
)

# --------------------------------------------------------- reorder buffer


def _stamps(batches: Sequence[DetectionBatch]) -> list[tuple[str, float]]:
    return [(b.sensor_id, round(b.stamp, 6)) for b in batches]


def test_reorder_buffer_releases_in_capture_order() -> None:
    rng = np.random.default_rng(2)
    latency = {"a": 0.01, "b": 0.045}  # b's frames arrive after a's later frames
    items = []
    for k in range(90):
        for sensor, phase in (("a", 0.0), ("b", 0.011)):
            stamp = T0 + k * FRAME + phase
            arrival = stamp + latency[sensor] + rng.uniform(0, 0.004)
            items.append((arrival, make_batch(stamp, sensor=sensor, seq=k)))
    items.sort(key=lambda item: item[0])
    assert [b.stamp for _, b in items] != sorted(b.stamp for _, b in items)  # really reordered
    buf = ReorderBuffer(window_s=0.1)
    released: list[DetectionBatch] = []
    startup = None  # a sensor never heard from is not waited for
    for arrival, batch in items:
        if startup is None and batch.sensor_id == "b":
            startup = len(released)
        released += buf.release(arrival)
        released += buf.push(batch, arrival)
    released += buf.flush()
    assert len(buf) == 0
    assert sorted(_stamps(released)) == sorted(_stamps([b for _, b in items]))
    assert startup is not None
    assert startup <= 2
    stamps = [b.stamp for b in released[startup:]]
    assert stamps == sorted(stamps)


def test_reorder_buffer_with_zero_window_releases_immediately() -> None:
    buf = ReorderBuffer(window_s=0.0)
    assert buf.push(make_batch(10.0, sensor="a"), 10.01) != []
    assert buf.push(make_batch(10.0, sensor="b"), 10.02) != []
    later = make_batch(10.5, sensor="a")
    assert buf.push(later, 10.51) == [later]  # b may still deliver 10.4: no wait
    earlier = make_batch(10.4, sensor="b")
    assert buf.push(earlier, 10.52) == [earlier]  # arrival order, not capture order
    assert len(buf) == 0


def test_reorder_buffer_releases_early_when_the_other_sensor_is_ahead() -> None:
    buf = ReorderBuffer(window_s=0.5)
    assert _stamps(buf.push(make_batch(9.0, sensor="a"), 9.01)) == [("a", 9.0)]
    assert _stamps(buf.push(make_batch(9.0, sensor="b"), 9.02)) == [("b", 9.0)]
    assert buf.push(make_batch(9.5, sensor="a"), 9.51) == []  # b might deliver something earlier
    assert buf.release(9.9) == []
    # b delivers a later frame: a's batch goes long before its window ends
    assert _stamps(buf.push(make_batch(9.6, sensor="b"), 9.61)) == [("a", 9.5), ("b", 9.6)]
    # without that frame it would have waited for the whole window
    buf2 = ReorderBuffer(window_s=0.5)
    buf2.push(make_batch(9.0, sensor="a"), 9.01)
    buf2.push(make_batch(9.0, sensor="b"), 9.02)
    buf2.push(make_batch(9.5, sensor="a"), 9.51)
    assert buf2.release(10.0) == []
    assert _stamps(buf2.release(10.02)) == [("a", 9.5)]


def test_reorder_buffer_uses_the_other_sensors_frame_period() -> None:
    buf = ReorderBuffer(window_s=1.0)
    for k in range(5):  # b at 30 Hz, last frame at T0 + 4/30
        buf.push(make_batch(T0 + k * FRAME, sensor="b", seq=k), T0 + k * FRAME + 0.01)
    last_b = T0 + 4 * FRAME
    # b's next frame cannot be captured before ~last_b + 1/30: earlier a frames go at once
    soon = make_batch(last_b + 0.3 * FRAME, sensor="a")
    assert buf.push(soon, last_b + 0.02) == [soon]
    # a frame captured after b's next expected frame waits for it
    late = make_batch(last_b + 0.95 * FRAME, sensor="a")
    assert buf.push(late, last_b + 0.021) == []
    b_next = make_batch(last_b + FRAME, sensor="b", seq=5)
    assert _stamps(buf.push(b_next, last_b + FRAME + 0.01)) == _stamps([late, b_next])


def test_reorder_buffer_does_not_wait_for_a_silent_sensor() -> None:
    buf = ReorderBuffer(window_s=5.0, sensor_timeout_s=1.0)
    buf.push(make_batch(9.0, sensor="a"), 9.01)
    buf.push(make_batch(9.0, sensor="b"), 9.02)
    assert buf.push(make_batch(9.5, sensor="a"), 9.51) == []  # b silent 0.49 s: waited for
    assert _stamps(buf.push(make_batch(10.5, sensor="a"), 10.51)) == [("a", 9.5), ("a", 10.5)]
    assert len(buf) == 0


def test_reorder_buffer_rejects_negative_window() -> None:
    with pytest.raises(ValueError, match="window_s"):
        ReorderBuffer(window_s=-0.01)


# ------------------------------------------------------ sensor clock offsets


def _clock_stream(
    offsets: dict[str, float], seconds: float, seed: int = 0
) -> list[tuple[DetectionBatch, float, float]]:
    """``(batch, arrival, capture)`` of 30 Hz sensors whose clocks are off by ``offsets``."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(int(seconds * 30)):
        for i, (sensor, offset) in enumerate(offsets.items()):
            capture = T0 + k * FRAME + 0.007 * i
            arrival = capture + 0.03 + rng.exponential(0.02)  # jitter only adds delay
            batch = make_batch(capture + offset, [det(2.0, 2.0)], sensor=sensor, seq=k)
            out.append((batch, arrival, capture))
    out.sort(key=lambda item: item[1])
    return out


def test_clock_aligner_estimates_a_constant_offset() -> None:
    aligner = ClockAligner()
    assert aligner.correction("a") == 0.0
    for batch, arrival, _ in _clock_stream({"a": 0.0, "b": 0.0, "c": 0.15}, seconds=3.0):
        aligner.observe(batch.sensor_id, batch.stamp, arrival)
    corrections = aligner.corrections()
    # "seconds to add to this sensor's stamps": c's clock is 0.15 s ahead
    assert corrections["c"] == pytest.approx(-0.15, abs=0.005)
    assert corrections["a"] == pytest.approx(0.0, abs=0.005)
    assert corrections["b"] == pytest.approx(0.0, abs=0.005)
    assert aligner.correction("unknown") == 0.0


def test_pipeline_aligns_a_sensor_clock_offset() -> None:
    stream = _clock_stream({"a": 0.0, "b": 0.0, "c": 0.15}, seconds=3.0)
    captures = {(b.sensor_id, b.seq): capture for b, _, capture in stream}
    pipe = TrackingPipeline(build_tracker(), window_s=0.05, clock_correction="arrival")
    errors: dict[str, list[float]] = {}
    for batch, arrival, _ in stream:
        for used, _out in pipe.push(batch, arrival):
            errors.setdefault(used.sensor_id, []).append(
                used.stamp - captures[(used.sensor_id, used.seq)]
            )
    for sensor in "abc":
        assert np.median(errors[sensor][-30:]) == pytest.approx(0.0, abs=0.01), sensor


def test_pipeline_without_correction_keeps_stamps() -> None:
    stream = _clock_stream({"a": 0.0, "c": 0.15}, seconds=1.0)
    pipe = TrackingPipeline(build_tracker(), window_s=0.05, clock_correction="none")
    assert pipe.aligner is None
    sent = {(b.sensor_id, b.seq): b.stamp for b, _, _ in stream}
    used = [b for batch, arrival, _ in stream for b, _ in pipe.push(batch, arrival)]
    used += [b for b, _ in pipe.flush()]
    assert len(used) == len(sent)
    assert all(b.stamp == sent[(b.sensor_id, b.seq)] for b in used)
