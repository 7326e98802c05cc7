"""Robust track management on hand-built streams with realistic detection errors.

The streams are built here, independently of the simulator: two sensors at 30 Hz whose
detections of a person carry a white error, an error that persists over about a second
(a detector's centroid sits consistently off on one body), outliers, and misses; one
sensor is also offset as a calibration error would leave it. The figures (about 0.10 m
mean error) are those the childcare tracking paper measured on real children.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pytest

from openptrack_py.config import TrackerConfig
from openptrack_py.messages.detection import Detection, DetectionBatch
from openptrack_py.tracking import Tracker, build_tracker
from tests.cores import map_on_cores
from tests.tracking.helpers import FRAME, T0

SENSORS = ("a", "b")
OFFSET = {"a": np.zeros(2), "b": np.array([0.08, -0.06])}  # sensor b's calibration error


@dataclass
class _Errors:
    """White, persistent (Ornstein-Uhlenbeck, 1 s) and outlier errors per sensor."""

    rng: np.random.Generator
    white_m: float = 0.06
    persistent_m: float = 0.05
    outlier_p: float = 0.04
    outlier_m: float = 0.3
    state: dict[str, np.ndarray] = field(default_factory=dict)

    def draw(self, sensor: str) -> np.ndarray:
        keep = math.exp(-FRAME / 1.0)
        old = self.state.get(sensor, self.rng.normal(0, self.persistent_m, 2))
        new = keep * old + self.rng.normal(0, self.persistent_m * math.sqrt(1 - keep**2), 2)
        self.state[sensor] = new
        err = new + self.rng.normal(0, self.white_m, 2) + OFFSET[sensor]
        if self.rng.random() < self.outlier_p:
            err = err + self.rng.normal(0, self.outlier_m, 2)
        return err


def _detection(xy: np.ndarray, conf: float) -> Detection:
    return Detection(
        x=float(xy[0]), y=float(xy[1]), z=1.0, height=1.7, confidence=conf, distance=4.0
    )


DECOY_RATE = 0.4
"""How often each sensor reports the decoy while it shows: the ``harsh`` simulator
profile's rate (the ``realistic`` one's is 0.15), well above what the sensors of the
OpenPTrack paper reported (3-9 % false positives per person in view)."""


def _walks_in(t: float) -> np.ndarray:
    """Walks in from (0.5, 1) to (3, 3) over 5 s, then stands there."""
    start, stop = np.array([0.5, 1.0]), np.array([3.0, 3.0])
    return start + min(t / 5.0, 1.0) * (stop - start)


def _stands(t: float) -> np.ndarray:
    """Stands at (3, 3) from the start."""
    return np.array([3.0, 3.0])


def _run(
    tracker: Tracker,
    seconds: float,
    seed: int,
    *,
    person: bool,
    decoy: bool,
    person_at: Callable[[float], np.ndarray] = _walks_in,
    decoy_rate: float = DECOY_RATE,
) -> tuple[list[set[int]], list[set[int]]]:
    """Feed the stream; return, per step, the confirmed ids near the person / the decoy."""
    rng = np.random.default_rng(seed)
    person_err, decoy_err = _Errors(rng), _Errors(rng, outlier_p=0.02)
    decoy_xy = np.array([6.0, 1.5])  # a coat rack, 3 m from where the person stands
    near_person, near_decoy = [], []
    for k in range(int(seconds / FRAME)):
        for i, sensor in enumerate(SENSORS):
            t = k * FRAME + 0.011 * i
            dets = []
            truth = person_at(t)
            if person and rng.random() > 0.1:
                dets.append(_detection(truth + person_err.draw(sensor), rng.uniform(0.6, 0.95)))
            # the static false positive: it recurs at the same spot, in bursts, as
            # confidently as a person (0.5-0.8)
            if decoy and (t % 7.0) < 5.0 and rng.random() < decoy_rate:
                dets.append(_detection(decoy_xy + decoy_err.draw(sensor), rng.uniform(0.5, 0.8)))
            out = tracker.step(DetectionBatch(sensor, k, T0 + t, "world", tuple(dets)))
            confirmed = [tr for tr in out.tracks if tr.confirmed]
            near_person.append(
                {tr.id for tr in confirmed if math.hypot(tr.x - truth[0], tr.y - truth[1]) < 1.0}
            )
            near_decoy.append(
                {tr.id for tr in confirmed
                 if math.hypot(tr.x - decoy_xy[0], tr.y - decoy_xy[1]) < 1.0}
            )  # fmt: skip
    return near_person, near_decoy


STILL_SEEDS = (0, 1)


def _five_minutes(seed: int) -> tuple[list[set[int]], list[set[int]]]:
    """Five minutes: a person walks in and stands still; a decoy recurs at one spot."""
    return _run(build_tracker(TrackerConfig()), 300.0, seed, person=True, decoy=True)


@pytest.fixture(scope="module")
def five_minutes() -> dict[int, tuple[list[set[int]], list[set[int]]]]:
    """Both seeds' runs, made at once on every core."""
    return dict(zip(STILL_SEEDS, map_on_cores(_five_minutes, STILL_SEEDS), strict=True))


@pytest.mark.slow
@pytest.mark.parametrize("seed", STILL_SEEDS, ids=[f"seed{s}" for s in STILL_SEEDS])
def test_still_person_keeps_their_id_and_static_false_positive_is_never_confirmed(
    seed: int, five_minutes: dict[int, tuple[list[set[int]], list[set[int]]]]
) -> None:
    """Five minutes: a person walks in and stands still; a decoy recurs at one spot."""
    near_person, near_decoy = five_minutes[seed]
    ids = set().union(*near_person[int(10 / FRAME) :])
    assert len(ids) == 1, f"the standing person had ids {ids}"
    shown = sum(bool(s) for s in near_person[int(10 / FRAME) :]) / len(near_person[300:])
    assert shown > 0.99
    assert not set().union(*near_decoy), "the static false positive was confirmed"


@pytest.mark.slow
def test_without_the_displacement_rule_the_static_false_positive_is_confirmed() -> None:
    """The control: the same stream confirms the decoy when a track need not move."""
    tracker = build_tracker(TrackerConfig(confirm_min_displacement_m=0.0))
    _, near_decoy = _run(tracker, 20.0, 0, person=False, decoy=True)
    assert set().union(*near_decoy)


@pytest.mark.parametrize("seed", [0, 1], ids=["seed0", "seed1"])
def test_person_standing_still_from_the_start_is_confirmed_by_steadiness(seed: int) -> None:
    """Nobody moves: the person, detected in 90 % of frames, is confirmed within 1.5 s."""
    tracker = build_tracker(TrackerConfig())
    near_person, near_decoy = _run(tracker, 10.0, seed, person=True, decoy=True, person_at=_stands)
    first = next(k for k, ids in enumerate(near_person) if ids)
    assert first * FRAME / len(SENSORS) < 1.5
    assert len(set().union(*near_person)) == 1
    assert not set().union(*near_decoy)


def test_a_decoy_seen_as_often_as_a_person_is_confirmed_unless_the_rule_is_off() -> None:
    """The limit of steadiness, stated: a decoy reported in 90 % of frames looks like a
    person standing still; with ``confirm_still_error=0`` only moving is evidence."""
    seen = build_tracker(TrackerConfig())
    _, near_decoy = _run(seen, 10.0, 0, person=False, decoy=True, decoy_rate=0.9)
    assert set().union(*near_decoy)
    strict = build_tracker(TrackerConfig(confirm_still_error=0.0))
    _, near_decoy = _run(strict, 10.0, 0, person=False, decoy=True, decoy_rate=0.9)
    assert not set().union(*near_decoy)


def test_one_person_seen_by_two_offset_noisy_sensors_is_one_track() -> None:
    tracker = build_tracker(TrackerConfig())
    near_person, _ = _run(tracker, 30.0, 3, person=True, decoy=False)
    ids = set().union(*near_person)
    assert len(ids) == 1, ids  # outliers may start tentative tracks, never confirmed ones


def test_published_confidence_reflects_the_evidence() -> None:
    """A person seen in every frame is published more confidently than one seen rarely."""
    tracker = build_tracker(TrackerConfig(confirm_min_displacement_m=0.0))
    rng = np.random.default_rng(5)
    confidence: dict[int, list[float]] = {1: [], 2: []}
    for k in range(int(20 / FRAME)):
        t = k * FRAME
        dets = [_detection(np.array([1.0 + 0.3 * t, 1.0]), 0.9)]
        if k < 60 or rng.random() < 0.35:  # the second person, seen in a third of frames
            dets.append(_detection(np.array([1.0 + 0.3 * t, 4.0]), 0.9))
        out = tracker.step(DetectionBatch("a", k, T0 + t, "world", tuple(dets)))
        if t > 10:
            for tr in out.tracks:
                confidence[1 if tr.y < 2.5 else 2].append(tr.confidence)
    assert np.mean(confidence[1]) > 0.8
    assert np.mean(confidence[2]) < 0.6 * np.mean(confidence[1])


MISALIGNED = {  # sensor: (position, where its calibration puts its detections)
    "a": (np.array([0.0, 0.0]), np.array([0.21, 0.21])),
    "b": (np.array([6.0, 0.0]), np.array([-0.30, 0.05])),
    "c": (np.array([3.0, 6.0]), np.array([0.10, -0.28])),
}
"""Three corner sensors, each placed 0.3 m off by its calibration (and turned 3 degrees
about itself): the far end of the OpenPTrack paper's errors before refinement."""


def _seen_misaligned(sensor: str, xy: np.ndarray) -> np.ndarray:
    where, offset = MISALIGNED[sensor]
    c, s = math.cos(math.radians(3.0)), math.sin(math.radians(3.0))
    rel = xy - where
    return where + np.array([c * rel[0] - s * rel[1], s * rel[0] + c * rel[1]]) + offset


def _one_track_each(config: TrackerConfig) -> float:
    """Share of the steps after 10 s with exactly one confirmed track on each of three
    people walking a circle, seen by three quiet sensors 0.3 m and 3 degrees off."""
    rng = np.random.default_rng(0)
    tracker = build_tracker(config)
    one_each, steps = 0, 0
    for k in range(int(20.0 / FRAME)):
        for i, sensor in enumerate(MISALIGNED):
            t = k * FRAME + 0.011 * i
            people = [
                np.array(
                    [3 + 1.5 * math.cos(0.4 * t + 2.1 * p), 3 + 1.5 * math.sin(0.4 * t + 2.1 * p)]
                )
                for p in range(3)
            ]
            dets = tuple(
                _detection(_seen_misaligned(sensor, xy) + rng.normal(0, 0.02, 2), 0.9)
                for xy in people
                if rng.random() > 0.1
            )
            out = tracker.step(DetectionBatch(sensor, k, T0 + t, "world", dets))
            if t > 10.0:
                confirmed = [(tr.x, tr.y) for tr in out.tracks if tr.confirmed]
                steps += 1
                one_each += len(confirmed) == 3 and all(
                    sum(math.hypot(x - p[0], y - p[1]) < 0.6 for x, y in confirmed) == 1
                    for p in people
                )
    return one_each / steps


def test_sensors_30_cm_off_split_everyone_when_their_calibrations_are_trusted() -> None:
    """The control: with no calibration uncertainty each sensor starts its own track of
    every person, no track is fed by two sensors, and no misalignment is learned (with
    twins not used to learn it either)."""
    assert _one_track_each(TrackerConfig(align_from_twins=False)) < 0.5


def test_sensors_30_cm_off_give_each_person_one_track_given_their_calibrations_uncertainty() -> (
    None
):
    """Told that calibrations may be 0.12 m and 2 degrees off until learned, the tracker
    lets a sensor's detections feed another sensor's tracks, learns each misalignment,
    and keeps one track per person."""
    config = TrackerConfig(
        calibration_sigma_m=0.12, calibration_sigma_deg=2.0, align_from_twins=False
    )
    assert _one_track_each(config) > 0.95


def test_sensors_30_cm_off_give_each_person_one_track_from_the_map_their_twins_agree_on() -> None:
    """With nothing told about the calibrations: each sensor's own tracks of the three
    walkers are twins of the others', one rigid map per pair of sensors explains them
    all, and the alignments learned from it make one track per person."""
    assert _one_track_each(TrackerConfig()) > 0.95


def _couples(config: TrackerConfig) -> tuple[float, float]:
    """Two calibrated sensors; two couples walk side by side 0.6 m apart, sensor a seeing
    one of each couple and sensor b the other (as if each hid the far one), and a fifth
    person walks where both see them. Share of the steps after 10 s with five confirmed
    tracks, and the largest shift either sensor learned."""
    rng = np.random.default_rng(0)
    tracker = build_tracker(config)
    five, steps = 0, 0
    for k in range(int(30.0 / FRAME)):
        for i, sensor in enumerate("ab"):
            t = k * FRAME + 0.011 * i
            people = [
                np.array([4 + 3 * math.sin(0.25 * t + c), 1 + 2 * c + 0.6 * i]) for c in range(2)
            ]
            people.append(np.array([2 + 2 * math.cos(0.3 * t), 6 + 1.5 * math.sin(0.3 * t)]))
            dets = tuple(
                _detection(xy + rng.normal(0, 0.03, 2), 0.9) for xy in people if rng.random() > 0.1
            )
            out = tracker.step(DetectionBatch(sensor, k, T0 + t, "world", dets))
            if t > 10.0:
                steps += 1
                five += sum(tr.confirmed for tr in out.tracks) == 5
    shifts = [math.hypot(s["bias_x_m"], s["bias_y_m"]) for s in tracker.sensors.summary().values()]
    return five / steps, max(shifts)


def test_couples_seen_one_each_are_not_twins_where_a_shared_person_says_sensors_agree() -> None:
    """Each couple alone is what a 0.6 m calibration error would show; the person both
    sensors see (their tracks shared) says the calibrations agree, so nothing is learned
    from the couples. (Without that person nothing tells the two apart: the aligner then
    takes the couples for twins.)"""
    for config in (TrackerConfig(align_from_twins=False), TrackerConfig()):
        share, shift = _couples(config)
        assert share > 0.95
        assert shift < 0.05
