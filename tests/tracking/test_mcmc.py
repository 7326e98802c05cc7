"""The childcare paper's MCMC particle-group tracker (the comparison tracker)."""

from __future__ import annotations

import numpy as np

from openptrack_py.messages.detection import Detection, DetectionBatch
from openptrack_py.tracking.mcmc import McmcParams, McmcTracker

T0 = 1_764_000_000.0


def _batch(k: int, *xy: tuple[float, float], sensor: str = "a") -> DetectionBatch:
    dets = tuple(
        Detection(x=x, y=y, z=0.9, height=1.7, confidence=0.9, distance=3.0,
                  appearance=(1, 2, 30, 2, 1, 0, 0, 0))
        for x, y in xy
    )  # fmt: skip
    return DetectionBatch(sensor, k, T0 + k / 30, "world", dets)


def test_one_walking_person_is_one_track_on_the_detected_area() -> None:
    tracker = McmcTracker()
    out = None
    for k in range(120):  # 4 s at 1 m/s along x
        out = tracker.step(_batch(k, (1.0 + k / 30, 2.0)))
    assert out is not None and len(out.tracks) == 1
    track = out.tracks[0]
    assert (track.x, track.y) == (1.0 + 119 / 30, 2.0)  # snapped to the area's centre
    assert abs(track.vx - 1.0) < 0.5 and abs(track.vy) < 0.5  # 40 particles: a rough velocity
    assert tracker.counters["steps"] == 120


def test_two_people_apart_are_two_groups_and_a_person_gone_is_forgotten() -> None:
    tracker = McmcTracker(McmcParams(forget_s=1.0))
    for k in range(60):
        tracker.step(_batch(k, (1.0, 1.0), (4.0, 1.0)))
    ids = {t.id for t in tracker.step(_batch(60, (1.0, 1.0), (4.0, 1.0))).tracks}
    assert len(ids) == 2
    for k in range(61, 120):  # the second person leaves
        out = tracker.step(_batch(k, (1.0, 1.0)))
    assert len(out.tracks) == 1 and out.tracks[0].id in ids


def test_every_sensors_detections_of_one_person_are_one_area() -> None:
    tracker = McmcTracker()
    for k in range(90):
        sensor = "abc"[k % 3]
        offset = {"a": 0.0, "b": 0.15, "c": -0.1}[sensor]  # calibrations that disagree
        out = tracker.step(_batch(k, (2.0 + offset, 2.0), sensor=sensor))
    assert len(out.tracks) == 1


def test_a_false_positive_seen_once_starts_nothing_and_runs_repeat() -> None:
    def run() -> list[tuple[int, float, float]]:
        tracker = McmcTracker()
        tracks = []
        for k in range(60):
            extra = [(6.0, 5.0)] if k == 30 else []
            out = tracker.step(_batch(k, (1.0 + k / 30, 2.0), *extra))
            tracks += [(t.id, t.x, t.y) for t in out.tracks]
        return tracks

    first = run()
    assert {i for i, _, _ in first} == {1}
    assert first == run()  # seeded: the same chains every time
    assert np.isfinite([x for _, x, _ in first]).all()
