"""Admission control: well-formed batches that would harm the tracker are refused."""

from __future__ import annotations

import pytest

from openptrack_py.messages.detection import Detection, DetectionBatch
from openptrack_py.tracking.admission import RESYNC_BATCHES, Admission, SensorLimits

T0 = 1_700_000_000.0
LIMITS = {"a": SensorLimits(30.0, 5), "b": SensorLimits(15.0, 5)}


def _batch(sensor: str, k: int, stamp: float, n: int = 1, frame: str = "world") -> DetectionBatch:
    dets = tuple(
        Detection(
            x=float(i),
            y=0.0,
            z=0.9,
            height=1.7,
            confidence=min(0.5 + 0.0002 * i, 1.0),
            distance=3.0,
        )
        for i in range(n)
    )
    return DetectionBatch(sensor, k, stamp, frame, dets)


def _stream(adm: Admission, sensor: str, start: float, seconds: float, rate: float) -> int:
    """Feed a well-behaved sensor (50 ms latency); return how many were admitted."""
    admitted = 0
    for k in range(int(seconds * rate)):
        t = start + k / rate
        admitted += adm.admit(sensor, _batch(sensor, k, t), t + 0.05) is not None
    return admitted


def test_a_well_behaved_network_is_admitted_whole() -> None:
    adm = Admission(LIMITS)
    assert _stream(adm, "a", T0, 5.0, 30.0) == 150
    assert _stream(adm, "b", T0, 5.0, 15.0) == 75
    assert not any(adm.counters.values())


def test_one_batch_stamped_far_in_the_future_is_refused_and_blinds_nobody() -> None:
    adm = Admission(LIMITS)
    _stream(adm, "a", T0, 2.0, 30.0)
    now = T0 + 2.0
    assert adm.admit("a", _batch("a", 999, now + 1e6), now) is None
    assert adm.counters["bad_stamp"] == 1
    assert _stream(adm, "a", now, 2.0, 30.0) == 60  # the very next batch is taken
    assert adm.admit("a", _batch("a", 998, now - 1e6), now + 2.0) is None  # far past too
    assert adm.counters["bad_stamp"] == 2


def test_a_real_clock_step_is_adopted_after_batches_agree_on_it() -> None:
    adm = Admission(LIMITS)
    _stream(adm, "a", T0, 2.0, 30.0)
    jumped = T0 + 2.0 + 30.0  # NTP stepped the sensor's clock 30 s ahead
    admitted = [
        adm.admit("a", _batch("a", k, jumped + k / 30), T0 + 2.0 + k / 30 + 0.05) is not None
        for k in range(60)
    ]
    assert admitted.index(True) == RESYNC_BATCHES - 1
    assert all(admitted[RESYNC_BATCHES - 1 :])


def test_a_first_batch_far_from_the_arrival_time_is_refused() -> None:
    adm = Admission(LIMITS, max_clock_offset_s=3600.0)
    assert adm.admit("a", _batch("a", 0, T0 + 7200.0), T0) is None
    assert adm.admit("a", _batch("a", 1, T0 + 1800.0), T0) is not None  # an hour off is fine


def test_a_batch_on_another_sensors_key_is_refused() -> None:
    adm = Admission(LIMITS)
    assert adm.admit("b", _batch("a", 0, T0), T0) is None
    assert adm.counters["sensor_mismatch"] == 1
    assert adm.admit("a", _batch("a", 0, T0), T0) is not None


def test_unknown_sensors_are_refused_unless_discovered_and_then_forgotten() -> None:
    strict = Admission(LIMITS)
    for i in range(5000):
        assert strict.admit(f"x{i}", _batch(f"x{i}", 0, T0), T0) is None
    assert strict.counters["unknown_sensor"] == 5000 and strict.sensors() == []
    open_ = Admission(LIMITS, discover_sensors=True, sensor_forget_s=10.0)
    for i in range(100):
        assert open_.admit(f"x{i}", _batch(f"x{i}", 0, T0), T0) is not None
    _stream(open_, "a", T0 + 20.0, 1.0, 30.0)  # later traffic prunes the silent ones
    assert open_.sensors() == ["a"]


def test_a_batch_in_another_frame_is_refused() -> None:
    adm = Admission(LIMITS, frame_id="world")
    assert adm.admit("a", _batch("a", 0, T0, frame="a"), T0) is None
    assert adm.counters["wrong_frame"] == 1


@pytest.mark.parametrize("sensor, rate", [("a", 30.0), ("b", 15.0)])
def test_a_flood_is_cut_to_twice_the_sensors_rate(sensor: str, rate: float) -> None:
    adm = Admission(LIMITS)
    admitted = sum(
        adm.admit(sensor, _batch(sensor, k, T0 + k / 2500), T0 + k / 2500) is not None
        for k in range(5000)  # 2,500 batches a second for 2 s
    )
    # a second's worth of burst, then twice the nominal rate
    assert admitted == pytest.approx(2 * rate + 2 * 2 * rate, abs=2)
    assert adm.counters["rate_limited"] == 5000 - admitted


def test_detections_beyond_what_a_sensor_can_see_are_capped_most_confident_kept() -> None:
    adm = Admission(LIMITS)
    out = adm.admit("a", _batch("a", 0, T0, n=2000), T0)
    assert out is not None and len(out.detections) == 5
    assert sorted(d.x for d in out.detections) == [1995.0, 1996.0, 1997.0, 1998.0, 1999.0]
    assert adm.counters["detections_capped"] == 1995
