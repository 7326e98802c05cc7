"""Tests for openptrack_py.eval.metrics (CLEAR MOT and IDF1 on the ground plane)."""

from __future__ import annotations

import json
import math
from dataclasses import fields

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from openptrack_py.eval.metrics import MotAccumulator, MotMetrics, distance_matrix

GATE = 0.5


# --------------------------------------------------------------------------- helpers


def _walk(rng: np.random.Generator, n_frames: int, start: np.ndarray, step: float) -> np.ndarray:
    return start + np.cumsum(rng.normal(0.0, step, (n_frames, *start.shape)), axis=0)


def _far_apart_tracks(n_frames: int, n_objects: int) -> np.ndarray:
    """Positions (frames, objects, 2) of objects that never come within 2 m of each other."""
    t = np.arange(n_frames)[:, None]
    x = 0.01 * t + 3.0 * np.arange(n_objects)[None, :]
    y = 0.5 * np.sin(0.05 * t + np.arange(n_objects)[None, :])
    return np.stack([x, y], axis=-1)


# --------------------------------------------------------------------------- oracle


def test_ground_truth_against_itself_is_perfect() -> None:
    rng = np.random.default_rng(7)
    n_frames, n_objects = 300, 8
    pos = _walk(rng, n_frames, rng.uniform(0.0, 6.0, (n_objects, 2)), 0.05)
    births = rng.integers(0, 150, n_objects)
    deaths = births + rng.integers(20, 200, n_objects)
    ids = np.arange(n_objects) * 5 + 3
    acc = MotAccumulator(max_distance_m=GATE)
    total = 0
    for t in range(n_frames):
        alive = np.flatnonzero((births <= t) & (t < deaths))
        rng.shuffle(alive)
        total += alive.size
        acc.update(ids[alive], pos[t, alive], ids[alive], pos[t, alive])
    m = acc.compute()
    assert total > 0
    assert m.frames == n_frames == acc.frames
    assert m.mota == 1.0
    assert m.motp == 0.0
    assert m.idf1 == m.idp == m.idr == 1.0
    assert m.precision == m.recall == 1.0
    assert (m.fp, m.fn, m.id_switches, m.fragmentations) == (0, 0, 0, 0)
    assert m.matches == m.gt_objects == m.hyp_objects == total
    assert m.gt_tracks == m.hyp_tracks == m.mostly_tracked == n_objects
    assert m.partially_tracked == m.mostly_lost == 0


# --------------------------------------------------------------------------- identity


@pytest.mark.parametrize("k", [30, 60])
def test_swap_of_two_identities_counts_two_switches(k: int) -> None:
    n = 100
    pos = _far_apart_tracks(n, 2)
    offset = np.array([0.1, 0.0])
    acc = MotAccumulator(max_distance_m=GATE)
    for t in range(n):
        hyp_ids = [7, 8] if t < k else [8, 7]
        acc.update([1, 2], pos[t], hyp_ids, pos[t] + offset)
    m = acc.compute()
    assert m.id_switches == 2
    assert (m.fp, m.fn, m.fragmentations) == (0, 0, 0)
    assert m.matches == 2 * n
    assert m.mota == pytest.approx(1.0 - 2 / (2 * n), abs=1e-12)
    assert m.motp == pytest.approx(0.1, abs=1e-12)
    # best identity mapping keeps the longer half of each track: IDTP = 2 * max(k, n - k)
    expected = max(k, n - k) / n
    assert m.idf1 == pytest.approx(expected, abs=1e-12)
    assert m.idp == pytest.approx(expected, abs=1e-12)
    assert m.idr == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("k", [30, 60])
def test_one_track_changing_id_counts_one_switch(k: int) -> None:
    n = 100
    pos = _far_apart_tracks(n, 2)
    acc = MotAccumulator(max_distance_m=GATE)
    for t in range(n):
        acc.update([1, 2], pos[t], [7 if t < k else 9, 8], pos[t] + 0.05)
    m = acc.compute()
    assert m.id_switches == 1
    assert (m.fp, m.fn, m.fragmentations) == (0, 0, 0)
    assert m.hyp_tracks == 3 and m.gt_tracks == 2
    assert m.mota == pytest.approx(1.0 - 1 / (2 * n), abs=1e-12)
    # IDTP = longer part of track 1 + all of track 2
    expected = (max(k, n - k) + n) / (2 * n)
    assert m.idf1 == pytest.approx(expected, abs=1e-12)
    assert m.idp == pytest.approx(expected, abs=1e-12)
    assert m.idr == pytest.approx(expected, abs=1e-12)


def test_switch_is_measured_against_last_match_in_any_earlier_frame() -> None:
    acc = MotAccumulator(max_distance_m=GATE)
    for _ in range(10):
        acc.update([1], [[0.0, 0.0]], [7], [[0.1, 0.0]])
    for _ in range(5):  # gt 1 leaves the scene
        acc.update([], [], [], [])
    for _ in range(5):  # comes back, tracked under a new id
        acc.update([1], [[0.0, 0.0]], [8], [[0.1, 0.0]])
    m = acc.compute()
    assert m.id_switches == 1
    assert m.fragmentations == 0  # absent frames are not misses
    assert m.frames == 20


def test_reacquiring_same_id_after_misses_is_a_fragmentation_not_a_switch() -> None:
    acc = MotAccumulator(max_distance_m=GATE)
    for t in range(30):
        if 10 <= t < 13 or 20 <= t < 22:
            acc.update([1], [[0.0, 0.0]], [], [])
        else:
            acc.update([1], [[0.0, 0.0]], [7], [[0.2, 0.0]])
    m = acc.compute()
    assert m.id_switches == 0
    assert m.fragmentations == 2
    assert m.fn == 5
    assert m.mostly_tracked == 1  # 25 / 30 >= 0.8


def test_previous_correspondence_is_kept_over_a_closer_hypothesis() -> None:
    acc = MotAccumulator(max_distance_m=GATE)
    acc.update([1], [[0.0, 0.0]], [7], [[0.1, 0.0]])
    acc.update([1], [[0.0, 0.0]], [8, 7], [[0.05, 0.0], [0.4, 0.0]])
    m = acc.compute()
    assert (m.id_switches, m.fp, m.fn, m.matches) == (0, 1, 0, 2)
    assert m.motp == pytest.approx(0.25, abs=1e-12)


def test_assignment_maximises_matches_before_minimising_distance() -> None:
    # Nearest-first would take A-P (0.40) and leave B and Q unmatched; CLEAR MOT pairs
    # A-Q (0.42) and B-P (0.45).
    acc = MotAccumulator(max_distance_m=GATE)
    acc.update([1, 2], [[0.0, 0.0], [0.85, 0.0]], [7, 8], [[0.4, 0.0], [-0.42, 0.0]])
    m = acc.compute()
    assert (m.matches, m.fp, m.fn) == (2, 0, 0)
    assert m.motp == pytest.approx((0.42 + 0.45) / 2, abs=1e-12)


def test_mostly_tracked_partially_tracked_mostly_lost() -> None:
    acc = MotAccumulator(max_distance_m=GATE)
    pos = _far_apart_tracks(10, 3)
    for t in range(10):
        hyp_ids = [10] + ([20] if t < 5 else []) + ([30] if t < 1 else [])
        acc.update([1, 2, 3], pos[t], hyp_ids, pos[t, : len(hyp_ids)])
    m = acc.compute()
    # track 1: 10/10, track 2: 5/10, track 3: 1/10
    assert (m.mostly_tracked, m.partially_tracked, m.mostly_lost) == (1, 1, 1)


# --------------------------------------------------------------------------- missing frames


def test_missing_frames_add_misses_and_lower_mota() -> None:
    n_frames, n_objects, missing = 50, 3, range(20, 25)
    pos = _far_apart_tracks(n_frames, n_objects)
    ids = [4, 5, 6]
    acc = MotAccumulator(max_distance_m=GATE)
    same = MotAccumulator(max_distance_m=GATE)
    for t in range(n_frames):
        if t in missing:
            acc.update_missing_frame(ids, pos[t])
            same.update(ids, pos[t], [], np.empty((0, 2)))
        else:
            acc.update(ids, pos[t], [11, 12, 13], pos[t] + 0.1)
            same.update(ids, pos[t], [11, 12, 13], pos[t] + 0.1)
    m = acc.compute()
    k = len(missing)
    assert m == same.compute()
    assert m.frames == n_frames
    assert m.fn == k * n_objects
    assert (m.fp, m.id_switches) == (0, 0)
    assert m.fragmentations == n_objects
    assert m.mota == pytest.approx(1.0 - k * n_objects / (n_frames * n_objects), abs=1e-12)
    assert m.mota == pytest.approx(0.9, abs=1e-12)
    idtp = (n_frames - k) * n_objects  # every hypothesis is an identity true positive
    assert m.hyp_objects == idtp
    assert m.idf1 == pytest.approx(2 * idtp / (n_frames * n_objects + idtp), abs=1e-12)
    assert m.idp == 1.0
    assert m.idr == pytest.approx(0.9, abs=1e-12)


def test_missing_frame_with_no_ground_truth_counts_frame_only() -> None:
    acc = MotAccumulator()
    acc.update_missing_frame([], np.empty((0, 2)))
    m = acc.compute()
    assert m.frames == 1 and m.gt_objects == 0 and m.fn == 0
    assert math.isnan(m.mota) and math.isnan(m.motp)


# --------------------------------------------------------------------------- threshold


@pytest.mark.parametrize(
    ("hyp_xy", "matched"),
    [((0.49, 0.0), True), ((0.51, 0.0), False), ((0.5, 0.0), True), ((0.3, 0.4), True)],
)
def test_distance_threshold(hyp_xy: tuple[float, float], matched: bool) -> None:
    acc = MotAccumulator(max_distance_m=0.5)
    acc.update([1], [[0.0, 0.0]], [2], [hyp_xy])
    m = acc.compute()
    if matched:
        assert (m.matches, m.fp, m.fn, m.mota) == (1, 0, 0, 1.0)
        assert m.motp == pytest.approx(math.hypot(*hyp_xy), abs=1e-12)
    else:
        assert (m.matches, m.fp, m.fn) == (0, 1, 1)
        assert m.mota == -1.0
        assert math.isnan(m.motp)
        assert m.idf1 == 0.0


def test_three_dimensional_coordinates_use_height() -> None:
    acc = MotAccumulator(max_distance_m=0.5)
    # 0.424 m apart on the floor, 0.520 m apart in 3-D
    acc.update([1], [[0.0, 0.0, 1.0]], [2], [[0.3, 0.3, 1.3]])
    m = acc.compute()
    assert (m.matches, m.fp, m.fn) == (0, 1, 1)


def test_distance_matrix() -> None:
    d = distance_matrix([[0.0, 0.0], [3.0, 4.0]], [[0.3, 0.4], [3.0, 4.2], [9.0, 9.0]], 0.5)
    assert d.shape == (2, 3)
    assert d[0, 0] == pytest.approx(0.5)
    assert d[1, 1] == pytest.approx(0.2)
    assert np.isinf(d[0, 1]) and np.isinf(d[0, 2]) and np.isinf(d[1, 0]) and np.isinf(d[1, 2])
    assert distance_matrix(np.empty((0, 2)), [[1.0, 2.0]], 0.5).shape == (0, 1)
    assert distance_matrix([[1.0, 2.0, 3.0]], [], 0.5).shape == (1, 0)
    with pytest.raises(ValueError, match="max_distance_m"):
        distance_matrix([[0.0, 0.0]], [[0.0, 0.0]], 0.0)
    with pytest.raises(ValueError, match="gt_xy and hyp_xy"):
        distance_matrix([[0.0, 0.0]], [[0.0, 0.0, 0.0]], 1.0)


# --------------------------------------------------------------------------- validation


@pytest.mark.parametrize("bad", [0.0, -0.1, math.nan, math.inf, -math.inf, "far", None, True])
def test_constructor_rejects_bad_threshold(bad: object) -> None:
    with pytest.raises(ValueError, match=r"max_distance_m must be a finite number > 0.*got"):
        MotAccumulator(max_distance_m=bad)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("args", "pattern"),
    [
        (([1, 1], [[0, 0], [1, 1]], [], []), r"gt_ids must be unique.*\[1\]"),
        (([1], [[0, 0]], [3, 4, 3], [[0, 0], [1, 1], [2, 2]]), r"hyp_ids must be unique.*\[3\]"),
        (([1, 2], [[0, 0]], [], []), r"gt_xy has 1 rows but gt_ids has 2"),
        (([1], [[0, 0]], [2], [[0, 0], [1, 1]]), r"hyp_xy has 2 rows but hyp_ids has 1"),
        (([1], [[0, 0, 0, 0]], [], []), r"gt_xy must have shape \(n, 2\) or \(n, 3\)"),
        (([1], [[0, 0]], [2], [0, 0]), r"hyp_xy must have shape"),
        (([1], [[0, math.nan]], [], []), r"gt_xy contains non-finite"),
        (([1], [[0, 0]], [2], [[math.inf, 0]]), r"hyp_xy contains non-finite"),
        (([1.5], [[0, 0]], [], []), r"gt_ids must contain integers"),
        (([1], [[0, 0]], [[2]], [[0, 0]]), r"hyp_ids must be 1-D"),
        (([1], [[0, 0]], [2], [[0, 0, 0]]), r"gt_xy and hyp_xy must have the same number"),
        (([1], [["a", 0]], [], []), r"gt_xy must be an array"),
    ],
)
def test_update_rejects_bad_input(args: tuple, pattern: str) -> None:
    acc = MotAccumulator()
    acc.update([1], [[0.0, 0.0]], [2], [[0.1, 0.0]])
    before = acc.compute()
    with pytest.raises(ValueError, match=pattern):
        acc.update(*args)
    assert acc.frames == 1
    assert acc.compute() == before


def test_update_missing_frame_rejects_bad_input() -> None:
    acc = MotAccumulator()
    with pytest.raises(ValueError, match="gt_ids must be unique"):
        acc.update_missing_frame([2, 2], [[0.0, 0.0], [1.0, 1.0]])
    with pytest.raises(ValueError, match="gt_xy has 1 rows"):
        acc.update_missing_frame([2, 3], [[0.0, 0.0]])
    with pytest.raises(ValueError, match="gt_xy contains non-finite"):
        acc.update_missing_frame([2], [[0.0, math.nan]])
    assert acc.frames == 0


def test_empty_accumulator_and_to_dict_is_json_friendly() -> None:
    m = MotAccumulator().compute()
    assert m.frames == 0 and m.gt_tracks == 0 and m.hyp_tracks == 0
    for name in ("mota", "motp", "idf1", "idp", "idr", "precision", "recall"):
        assert math.isnan(getattr(m, name))
    d = m.to_dict()
    assert list(d) == [f.name for f in fields(MotMetrics)]
    assert d["mota"] is None and d["fp"] == 0
    json.dumps(d, allow_nan=False)

    acc = MotAccumulator()
    acc.update([1], [[0.0, 0.0]], [2], [[0.2, 0.0]])
    d = acc.compute().to_dict()
    assert d["mota"] == 1.0 and d["matches"] == 1 and isinstance(d["matches"], int)
    assert json.loads(json.dumps(d, allow_nan=False)) == d


def test_two_minutes_at_30_hz_with_every_track_renamed_once() -> None:
    rng = np.random.default_rng(3)
    n_frames, n_objects = 3600, 20
    pos = _walk(rng, n_frames, rng.uniform(0.0, 10.0, (n_objects, 2)), 0.03)
    ids = np.arange(n_objects)
    acc = MotAccumulator()
    for t in range(n_frames):
        keep = rng.random(n_objects) < 0.95
        hyp_ids = ids + 100 + 50 * (t >= n_frames // 2)  # every track renamed once
        noisy = pos[t] + rng.normal(0.0, 0.1, pos[t].shape)
        acc.update(ids, pos[t], hyp_ids[keep], noisy[keep])
    m = acc.compute()
    assert m.frames == n_frames and m.gt_objects == n_frames * n_objects
    assert m.id_switches >= n_objects


# --------------------------------------------------------------------------- duplicates

RATE_HZ = 30.0


def _duplicated(
    spans: list[tuple[int, float, float]], length_s: float = 4.0, offset_m: float = 0.2
) -> MotAccumulator:
    """One person walking along x, followed by track 1 all along and by the extra tracks
    ``(id, from_s, to_s)`` (``offset_m`` to the side) while their spans last."""
    acc = MotAccumulator(max_distance_m=GATE)
    for k in range(round(length_s * RATE_HZ) + 1):
        t = k / RATE_HZ
        x = 1.2 * t
        hyp_ids, hyp_xy = [1], [[x, 0.02]]
        for hid, start, end in spans:
            if start <= t + 1e-9 and t <= end + 1e-9:
                hyp_ids.append(hid)
                hyp_xy.append([x, offset_m])
        acc.update([7], [[x, 0.0]], hyp_ids, hyp_xy, time_s=100.0 + t)
    return acc


@pytest.mark.parametrize("lasting_s, counted", [(0.9, 0), (1.1, 1)])
def test_a_duplicate_counts_only_when_it_lasts_more_than_a_second(
    lasting_s: float, counted: int
) -> None:
    m = _duplicated([(2, 1.0, 1.0 + lasting_s)]).compute()
    assert m.duplicates == counted
    assert m.duplicate_s == pytest.approx(lasting_s if counted else 0.0, abs=1e-6)
    assert m.fp == round(lasting_s * RATE_HZ) + 1  # a duplicate is still a false positive
    assert m.id_switches == 0 and m.fn == 0


def test_a_duplicate_farther_than_the_match_distance_is_not_one() -> None:
    m = _duplicated([(2, 0.0, 3.0)], offset_m=GATE + 0.1).compute()
    assert m.duplicates == 0 and m.duplicate_s == 0.0 and m.fp > 0


def test_short_gaps_do_not_split_a_duplicate_episode_long_ones_do() -> None:
    # 0.6 s, a 0.1 s hole, 0.6 s: one episode of 1.3 s
    bridged = _duplicated([(2, 0.5, 1.1), (2, 1.2, 1.8)]).compute()
    assert bridged.duplicates == 1 and bridged.duplicate_s == pytest.approx(1.3, abs=1e-6)
    # 0.6 s, a 0.5 s hole, 0.6 s: two episodes too short to count
    split = _duplicated([(2, 0.5, 1.1), (2, 1.6, 2.2)]).compute()
    assert split.duplicates == 0


def test_successive_duplicates_under_other_ids_are_separate_episodes() -> None:
    m = _duplicated([(2, 0.5, 1.1), (3, 1.1 + 1 / RATE_HZ, 1.7)]).compute()
    assert m.duplicates == 0
    m = _duplicated([(2, 0.5, 1.7), (3, 2.0, 3.5)]).compute()
    assert m.duplicates == 2 and m.duplicate_s == pytest.approx(1.2 + 1.5, abs=1e-6)


def test_two_people_walking_side_by_side_are_not_duplicates() -> None:
    # each track is within the match distance of both people, but each person has one
    acc = MotAccumulator(max_distance_m=GATE)
    for k in range(120):
        t = k / RATE_HZ
        people = [[1.2 * t, 0.0], [1.2 * t, 0.35]]
        tracks = [[1.2 * t + 0.05, 0.05], [1.2 * t - 0.05, 0.3]]
        acc.update([1, 2], people, [11, 12], tracks, time_s=t)
    m = acc.compute()
    assert m.duplicates == 0 and m.fp == 0 and m.mota == 1.0


def test_one_track_between_two_people_is_no_duplicate() -> None:
    acc = MotAccumulator(max_distance_m=GATE)
    for k in range(120):
        acc.update([1, 2], [[0.0, 0.0], [0.0, 0.4]], [11], [[0.0, 0.2]], time_s=k / RATE_HZ)
    m = acc.compute()
    assert m.duplicates == 0 and m.fn == 120


def test_without_times_frames_follow_each_other_at_the_frame_rate() -> None:
    def run(rate_hz: float) -> MotMetrics:
        acc = MotAccumulator(max_distance_m=GATE, frame_rate_hz=rate_hz)
        for _ in range(40):  # 40 frames: 1.3 s at 30 Hz, 0.65 s at 60 Hz
            acc.update([1], [[0.0, 0.0]], [11, 12], [[0.0, 0.1], [0.1, 0.0]])
        return acc.compute()

    assert run(30.0).duplicates == 1 and run(30.0).duplicate_s == pytest.approx(1.3)
    assert run(60.0).duplicates == 0


@pytest.mark.parametrize(
    "kwargs", [{"duplicate_min_s": -1.0}, {"duplicate_gap_s": math.nan}, {"frame_rate_hz": 0.0}]
)
def test_constructor_rejects_bad_durations(kwargs: dict[str, float]) -> None:
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        MotAccumulator(**kwargs)


# --------------------------------------------------------------------------- motmetrics


def _motmetrics():
    if not hasattr(np, "asfarray"):
        np.asfarray = lambda a, dtype=float: np.asarray(a, dtype=dtype)  # type: ignore[attr-defined]
    return pytest.importorskip("motmetrics")


_MM_NAMES = {
    "mota": "mota",
    "motp": "motp",
    "idf1": "idf1",
    "idp": "idp",
    "idr": "idr",
    "precision": "precision",
    "recall": "recall",
    "id_switches": "num_switches",
    "fragmentations": "num_fragmentations",
    "fp": "num_false_positives",
    "fn": "num_misses",
    "matches": "num_detections",
    "frames": "num_frames",
    "gt_objects": "num_objects",
    "hyp_objects": "num_predictions",
    "gt_tracks": "num_unique_objects",
    "mostly_tracked": "mostly_tracked",
    "partially_tracked": "partially_tracked",
    "mostly_lost": "mostly_lost",
}


def _random_sequence(
    rng: np.random.Generator, n_frames: int, n_gt: int, dim: int
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """Random births/deaths, random walks, noisy hypotheses, relabelling, clutter."""
    area = rng.uniform(1.5, 5.0)
    pos = rng.uniform(0.0, area, (n_gt, dim))
    present = rng.random(n_gt) < 0.7
    present[0] = True
    p_toggle = rng.uniform(0.02, 0.15)
    p_detect = rng.uniform(0.6, 1.0)
    p_relabel = rng.uniform(0.0, 0.08)
    p_missing = rng.uniform(0.0, 0.1)
    noise = rng.uniform(0.05, 0.35) * GATE
    fp_rate = rng.uniform(0.0, 1.5)
    gt_label = rng.permutation(1000)[:n_gt] + 1  # arbitrary ints
    hyp_of = {g: 5000 + g for g in range(n_gt)}
    next_hyp = 6000
    frames = []
    for t in range(n_frames):
        if t:
            present ^= rng.random(n_gt) < p_toggle
            pos += rng.normal(0.0, 0.08, pos.shape)
        alive = np.flatnonzero(present)
        rng.shuffle(alive)
        for g in alive:
            if rng.random() < p_relabel:
                if rng.random() < 0.5 and n_gt > 1:
                    other = int(rng.integers(n_gt))
                    hyp_of[g], hyp_of[other] = hyp_of[other], hyp_of[g]
                else:
                    hyp_of[g] = next_hyp
                    next_hyp += 1
        hyp_ids: list[int] = []
        hyp_xy: list[np.ndarray] = []
        if rng.random() >= p_missing:
            for g in alive:
                if rng.random() < p_detect:
                    hyp_ids.append(hyp_of[g])
                    hyp_xy.append(pos[g] + rng.normal(0.0, noise, dim))
            used = set(hyp_ids)
            pool = [h for h in set(hyp_of.values()) | set(range(6000, next_hyp)) if h not in used]
            for _ in range(rng.poisson(fp_rate)):
                if pool and rng.random() < 0.5:
                    h = pool.pop(int(rng.integers(len(pool))))
                else:
                    h = next_hyp
                    next_hyp += 1
                hyp_ids.append(h)
                hyp_xy.append(rng.uniform(0.0, area, dim))
        order = rng.permutation(len(hyp_ids))
        frames.append(
            (
                gt_label[alive],
                pos[alive].copy(),
                np.asarray(hyp_ids, dtype=np.int64)[order],
                np.asarray(hyp_xy, dtype=float).reshape(-1, dim)[order],
            )
        )
    return frames


def _compare_with_motmetrics(frames: list) -> tuple[MotMetrics, dict]:
    mm = _motmetrics()
    ours = MotAccumulator(max_distance_m=GATE)
    theirs = mm.MOTAccumulator(auto_id=True)
    for gt_ids, gt_xy, hyp_ids, hyp_xy in frames:
        if hyp_ids.size == 0:
            ours.update_missing_frame(gt_ids, gt_xy)
        else:
            ours.update(gt_ids, gt_xy, hyp_ids, hyp_xy)
        d = np.linalg.norm(gt_xy[:, None, :] - hyp_xy[None, :, :], axis=2).reshape(
            gt_ids.size, hyp_ids.size
        )
        d[d > GATE] = np.nan
        theirs.update(gt_ids.tolist(), hyp_ids.tolist(), d)
    m = ours.compute()
    ref = mm.metrics.create().compute(
        theirs, metrics=sorted(set(_MM_NAMES.values())), return_dataframe=False
    )
    for ours_name, ref_name in _MM_NAMES.items():
        a, b = getattr(m, ours_name), ref[ref_name]
        if isinstance(a, int):
            assert a == int(b), (ours_name, a, b)
        elif math.isnan(a) or math.isnan(b):
            assert math.isnan(a) and math.isnan(b), (ours_name, a, b)
        else:
            assert a == pytest.approx(float(b), abs=1e-9, rel=0), (ours_name, a, b)
    assert m.hyp_tracks == len({h for f in frames for h in f[2].tolist()})
    return m, ref


@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1),
    n_frames=st.integers(1, 80),
    n_gt=st.integers(1, 9),
    dim=st.sampled_from([2, 3]),
)
def test_matches_motmetrics_on_random_sequences(
    seed: int, n_frames: int, n_gt: int, dim: int
) -> None:
    rng = np.random.default_rng(seed)
    _compare_with_motmetrics(_random_sequence(rng, n_frames, n_gt, dim))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_matches_motmetrics_on_long_crowded_sequences(seed: int) -> None:
    rng = np.random.default_rng(1000 + seed)
    m, _ = _compare_with_motmetrics(_random_sequence(rng, 150, 10, 2))
    # make sure the comparison exercised the interesting events
    assert m.id_switches > 0 and m.fragmentations > 0 and m.fp > 0 and m.fn > 0
