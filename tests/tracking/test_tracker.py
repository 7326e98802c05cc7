"""The tracker as a whole: role checks, and the gate widening while a person is unseen."""

from __future__ import annotations

import copy
import itertools
import math

import numpy as np
import pytest
from scipy.stats import chi2

from openptrack_py.config import TrackerConfig
from openptrack_py.tracking import (
    ChiSquareGater,
    ConfidenceInitiator,
    ConstantVelocity,
    GlobalNearestNeighbour,
    PositionMeasurement,
    StaticSensorModel,
    TimeDeleter,
    Tracker,
    build_tracker,
)
from tests.tracking.helpers import (
    FRAME,
    det,
    feed_still,
    make_batch,
)


def test_tracker_rejects_gate_of_wrong_dimension() -> None:
    with pytest.raises(ValueError, match="dof"):
        Tracker(
            ConstantVelocity(0.5),
            PositionMeasurement(0.08),
            ChiSquareGater(0.95, 4),
            GlobalNearestNeighbour(),
            ConfidenceInitiator(0.5, 3),
            TimeDeleter(2.4, 3.0),
        )


# --------------------------------------------- the gate widens while unseen


def _admission_radius(tracker: Tracker) -> float:
    """Largest distance (along +x from the prediction) at which track 0 takes a detection.

    Probes copies of the tracker with a detection at the tracker's current time, so no
    further prediction happens.
    """
    assert tracker.time is not None
    centre = tracker.table.x[0, 0:2].copy()
    track_id = int(tracker.table.ids[0])

    def admitted(r: float) -> bool:
        probe = copy.deepcopy(tracker)
        hits = int(probe.table.hits[0])
        probe.step(make_batch(tracker.time, [det(centre[0] + r, centre[1])], seq=999))
        row = int(np.flatnonzero(probe.table.ids == track_id)[0])
        return int(probe.table.hits[row]) > hits

    lo, hi = 0.0, 30.0
    assert admitted(lo)
    assert not admitted(hi)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if admitted(mid) else (lo, mid)
    return lo


def test_gate_widens_with_time_unseen() -> None:
    tracker = build_tracker(TrackerConfig(confirm_min_displacement_m=0.0, confirm_min_age_s=0.0))
    # the gate alone: no learned noise, and no clutter density narrowing it
    tracker.sensors = StaticSensorModel()
    last = feed_still(tracker, (3.0, 2.0), 6)
    assert tracker.table.confirmed.tolist() == [True]
    r_noise = PositionMeasurement(0.08, 0.002).noise(np.array([3.0]))[0]
    fresh = copy.deepcopy(tracker)
    fresh.step(make_batch(last + FRAME, seq=50))  # right after an update: one frame, no detection
    unseen = [FRAME, 0.25, 0.5, 1.0, 1.5, 2.0, 2.5]
    innovations, radii = [], []
    for tau in unseen:
        probe = copy.deepcopy(tracker)
        probe.step(make_batch(last + tau, seq=60))
        s = probe.table.cov[0, 0:2, 0:2] + r_noise
        innovations.append(s)
        radius = _admission_radius(probe)
        radii.append(radius)
        # the probed gate is exactly the chi-square gate on the predicted innovation
        expected = math.sqrt(probe.gater.threshold / np.linalg.inv(s)[0, 0])
        assert radius == pytest.approx(expected, rel=1e-6)
    for a, b in itertools.pairwise(innovations):
        assert (np.linalg.eigvalsh(b - a) > 0).all()  # strictly larger in every direction
    assert all(b > a for a, b in itertools.pairwise(radii))
    # a detection admitted after 1 s unseen is outside the gate right after an update
    r_1s = radii[unseen.index(1.0)]
    assert r_1s > 3 * radii[0]
    # ... but it could still be that person: inside the wider birth gate, it starts nothing
    s_fresh = fresh.table.cov[0, 0:2, 0:2] + r_noise
    birth = math.sqrt(chi2.ppf(0.9999, 2) / np.linalg.inv(s_fresh)[0, 0])
    assert radii[0] < birth < 0.9 * r_1s
    for distance, starts in ((0.5 * (radii[0] + birth), 0), (1.2 * birth, 1)):
        probe = copy.deepcopy(fresh)
        started = probe.counters["tracks_started"]
        hits = int(probe.table.hits[0])
        centre = probe.table.x[0, 0:2]
        probe.step(make_batch(probe.time, [det(centre[0] + distance, centre[1])], seq=70))
        assert int(probe.table.hits[0]) == hits
        assert probe.counters["tracks_started"] == started + starts


def test_a_reconfigured_tracker_keeps_each_sensors_column() -> None:
    # the track table's per-sensor columns follow the old tracker's order of sensors
    # ("b" first); the new one keeps it, whatever order sensors come in after the change
    old = build_tracker(TrackerConfig())
    for k in range(30):
        for i, sensor in enumerate(("b", "a")):
            old.step(make_batch(k * FRAME + 0.01 * i, [det(1.0, 2.0)], sensor=sensor, seq=k))
    new = build_tracker(TrackerConfig())
    new.adopt_state(old)
    before = new.table.sensor_hit_t.copy()
    new.step(make_batch(30 * FRAME, [det(1.0, 2.0)], sensor="a", seq=30))
    changed = np.flatnonzero((new.table.sensor_hit_t != before).any(axis=0))
    assert changed.tolist() == [1]
