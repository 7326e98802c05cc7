"""A person beside another, whom only one sensor sees: kept alive by that sensor.

``keepalive_per_sensor``: beside other confirmed tracks, a sensor's own support of a
track, over its frames that detected each of them too, may keep the track alive, so
the sensors the neighbour hides the person from do not starve it; a second track on
one person's offset view gains no such support, an unsure detection says nothing, and
away from others a sensor that stops seeing a track takes its support away.
"""

from __future__ import annotations

import numpy as np
import pytest

from openptrack_py.config import TrackerConfig
from openptrack_py.messages.detection import Detection, DetectionBatch
from openptrack_py.tracking import build_tracker
from openptrack_py.tracking.bookkeeping import update_support
from openptrack_py.tracking.params import TrackerParams
from openptrack_py.tracking.state import SENSOR_SLOTS, TrackTable, sensor_slot
from tests.tracking.helpers import FRAME, T0

CHILD = np.array([3.25, 3.25])  # the middle of a coverage cell
NEIGHBOUR = np.array([3.85, 3.25])  # stands 0.6 m from the child, in the next cell
SENSORS = ("near", "far_a", "far_b")
HIDDEN_S = 8.0  # the child stands from 4 s; the neighbour arrives beside them at 8 s


def _at(t: float, start: tuple[float, float], stop: np.ndarray, arrives: float) -> np.ndarray:
    return np.asarray(start) + min(t / arrives, 1.0) * (stop - np.asarray(start))


def _det(xy: np.ndarray, rng: np.random.Generator) -> Detection:
    x, y = xy + rng.normal(0.0, 0.04, 2)
    return Detection(x=float(x), y=float(y), z=0.7, height=1.3, confidence=0.85, distance=3.5)


def _run(config: TrackerConfig, seconds: float, seed: int) -> list[set[int]]:
    """Per sensor frame once the neighbour stands, the confirmed ids at the child.

    A child walks in and stands at ``CHILD`` from 4 s, seen by every sensor in 95 % of
    its frames; a neighbour walks in and stands beside them from 8 s, seen by every
    sensor in 95 % of frames. From then on only ``near`` detects the child (in 95 % of
    its frames); the neighbour hides them from the other two. Ids within 0.3 m.
    """
    rng = np.random.default_rng(seed)
    tracker = build_tracker(config)
    at_child = []
    for k in range(int(seconds / FRAME)):
        for i, sensor in enumerate(SENSORS):
            t = k * FRAME + 0.011 * i
            dets = []
            if rng.random() < 0.95:
                dets.append(_det(_at(t, (6.25, 6.25), NEIGHBOUR, HIDDEN_S), rng))
            hidden = t >= HIDDEN_S
            if (sensor == "near" or not hidden) and rng.random() < 0.95:
                dets.append(_det(_at(t, (0.75, 0.75), CHILD, 4.0), rng))
            out = tracker.step(DetectionBatch(sensor, k, T0 + t, "world", tuple(dets)))
            if hidden:
                shown = [tr for tr in out.tracks if tr.confirmed]
                at_child.append({tr.id for tr in shown if np.hypot(*(CHILD - (tr.x, tr.y))) < 0.3})
    return at_child


@pytest.mark.parametrize("seed", [0, 1], ids=["seed0", "seed1"])
def test_a_child_hidden_from_two_sensors_by_a_neighbour_keeps_their_track(seed: int) -> None:
    at_child = _run(TrackerConfig(keepalive_per_sensor=True), 40.0, seed)
    assert np.mean([bool(ids) for ids in at_child]) > 0.99
    assert len(set().union(*at_child)) == 1
    # without it, the misses of the two sensors that do not see the child pull the
    # track's support below the keepalive floor, and the child is lost most of the time
    at_child = _run(TrackerConfig(), 40.0, seed)
    assert np.mean([bool(ids) for ids in at_child]) < 0.5


def _table(xy: list[list[float]], support: float = 0.2) -> TrackTable:
    n = len(xy)
    x = np.zeros((n, 4))
    x[:, 0:2] = xy
    return TrackTable(
        ids=np.arange(n),
        x=x,
        confirmed=np.ones(n, dtype=bool),
        support=np.full(n, support),
        evidence=np.zeros(n),
        sensor_hit_t=np.full((n, SENSOR_SLOTS), -np.inf),
        sensor_support=np.zeros((n, SENSOR_SLOTS)),
    )


BESIDE = TrackerParams(support_rate=0.5, keepalive_beside_m=1.0)
EVERYWHERE = np.ones(3, dtype=bool)


def test_a_sensor_that_detects_everyone_beside_a_track_moves_its_own_support() -> None:
    """Two tracks 0.6 m apart and one alone, all seen by this sensor: beside each other,
    a frame counts only where it detected both; alone, every frame counts, but the
    sensor's own support never keeps the lone track alive."""
    tb = _table([[0.0, 0.0], [0.6, 0.0], [5.0, 5.0]], support=0.1)
    slot = sensor_slot(1)
    tb.sensor_support[:, slot] = [0.9, 0.0, 0.9]
    keep = update_support(tb, np.array([0, 1, 2]), EVERYWHERE, 1, T0, BESIDE)
    # what held before the frame: the better of the track's support and, beside others,
    # the sensor's own; alone, the sensor's own says nothing
    assert keep.tolist() == [0.9, 0.1, 0.1]
    assert tb.sensor_support[:, slot].tolist() == [0.95, 0.5, 0.95]
    assert not np.delete(tb.sensor_support, slot, axis=1).any()
    # a frame that detects only the second: its neighbour was missed, so it counts for
    # the first (a miss) and not for the second, kept alive by its own support only
    keep = update_support(tb, np.array([1]), EVERYWHERE, 1, T0 + 0.03, BESIDE)
    assert keep.tolist() == [0.55]
    assert tb.sensor_support[:, slot].tolist() == [0.475, 0.5, 0.475]
    # both detected, but the second's detection was in the first's gate too (or the
    # second's gate held another): whose it was is not sure, so it says nothing
    update_support(tb, np.array([0, 1]), EVERYWHERE, 1, T0 + 0.06, BESIDE, certain=np.array([0]))
    assert tb.sensor_support[:, slot].tolist() == [0.7375, 0.5, 0.2375]


def test_a_second_track_on_one_sensors_offset_view_gains_no_support_of_its_own() -> None:
    """A person's track and a second one 0.6 m off, fed by one sensor that detects the
    person only there: every frame of that sensor misses the person's own track."""
    tb = _table([[0.0, 0.0], [0.6, 0.0]], support=0.5)
    slot = sensor_slot(2)
    tb.sensor_support[1, slot] = 0.9  # whatever it had, it is never used nor moved
    for k in range(30):
        held = tb.support[1]
        keep = update_support(tb, np.array([1]), EVERYWHERE[:2], 2, T0 + k / 30, BESIDE)
        assert keep.tolist() == [held]  # the track's own support, as without the rule
    assert tb.sensor_support[1, slot] == 0.9  # never counted
    assert tb.sensor_support[0, slot] == 0.0  # counted, a miss every time
