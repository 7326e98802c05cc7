"""Measurement models: OpenPTrack's velocity in the motion term."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from openptrack_py.config import TrackerConfig
from openptrack_py.tracking import (
    PositionVelocityMeasurement,
    build_tracker,
)
from tests.tracking.helpers import (
    FRAME,
    T0,
    det,
    make_batch,
)

# ------------------------------------------------ velocity in motion term


def test_velocity_in_motion_term_builds_a_4_dof_gate() -> None:
    cfg = TrackerConfig(velocity_in_motion_term=True, gate_probability=0.99)
    tracker = build_tracker(cfg)
    assert isinstance(tracker.measurement, PositionVelocityMeasurement)
    assert tracker.gater.dof == 4
    assert tracker.gater.threshold == pytest.approx(chi2.ppf(0.99, 4))


@pytest.mark.parametrize("velocity_term", [False, True], ids=["position", "velocity"])
def test_straight_walker_is_tracked(velocity_term: bool) -> None:
    rng = np.random.default_rng(5)
    tracker = build_tracker(TrackerConfig(velocity_in_motion_term=velocity_term))
    ids: set[int] = set()
    out = None
    for k in range(150):  # 5 s at 30 Hz, 1.2 m/s along x
        t = T0 + k * FRAME
        xy = np.array([1.0 + 1.2 * (t - T0), 2.0]) + rng.normal(0, 0.04, 2)
        out = tracker.step(make_batch(t, [det(*xy, distance=3.0)], seq=k))
        ids |= {tr.id for tr in out.tracks}
    assert out is not None
    assert ids == {1}
    assert tracker.counters["tracks_started"] == 1
    (track,) = out.tracks
    assert track.x == pytest.approx(1.0 + 1.2 * 149 * FRAME, abs=0.08)
    assert track.y == pytest.approx(2.0, abs=0.08)
    assert track.vx == pytest.approx(1.2, abs=0.15)
    assert track.vy == pytest.approx(0.0, abs=0.15)
