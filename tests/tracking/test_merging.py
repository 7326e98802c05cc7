"""Two confirmed tracks on one person are merged into the older; two people never are."""

from __future__ import annotations

import numpy as np
import pytest

from openptrack_py.config import TrackerConfig
from openptrack_py.messages.detection import Detection, DetectionBatch
from openptrack_py.tracking import TrackMerger, TrackTable, build_tracker
from openptrack_py.tracking.state import HISTORY, SENSOR_SLOTS
from tests.tracking.helpers import FRAME, T0


def _table(xy: list[tuple[float, float]], first_seen: list[float]) -> TrackTable:
    n = len(xy)
    table = TrackTable()
    table.ids = np.arange(1, n + 1)
    table.x = np.array([(x, y, 1.0, 0.0) for x, y in xy])
    table.confirmed = np.ones(n, dtype=bool)
    table.first_seen = np.array(first_seen)
    table.last_seen = np.full(n, 1e9)  # detected "now" at every query time
    table.sensor_hit_t = np.full((n, SENSOR_SLOTS), -np.inf)
    table.sensor_hit_t[:, 0] = 1e9
    return table


def test_close_tracks_merge_into_the_older_after_a_while() -> None:
    merger = TrackMerger(distance_m=0.35, after_s=0.5)
    table = _table([(1.0, 1.0), (1.2, 1.0)], first_seen=[-5.0, -1.0])
    assert merger.merge(table, 0.0) == []
    assert merger.merge(table, 0.3) == []
    assert merger.merge(table, 0.6) == [(0, 1)]


def test_a_duplicate_whose_support_has_fallen_is_still_merged() -> None:
    # The duplicate's confident detections no longer keep it alive (its support fell
    # below keepalive), but sensors still detect it: it is merged all the same. A
    # track nobody has detected lately (coasting past someone) is not.
    merger = TrackMerger(distance_m=0.35, after_s=0.5, fresh_s=0.3)
    table = _table([(1.0, 1.0), (1.2, 1.0)], first_seen=[-5.0, -1.0])
    table.last_seen[1] = -10.0
    table.sensor_hit_t[1] = -np.inf
    merged = []
    for t in np.arange(0.0, 1.0, 0.1):
        table.sensor_hit_t[1, 3] = t
        merged += merger.merge(table, t)
    assert merged == [(0, 1)]
    merger = TrackMerger(distance_m=0.35, after_s=0.5, fresh_s=0.3)
    table.sensor_hit_t[1] = -10.0
    assert all(merger.merge(table, t) == [] for t in np.arange(0.0, 2.0, 0.1))


def test_tracks_seen_in_one_frame_are_two_people() -> None:
    merger = TrackMerger(distance_m=0.35, after_s=0.5)
    table = _table([(1.0, 1.0), (1.2, 1.0)], first_seen=[-5.0, -1.0])
    for t in np.arange(0.0, 2.0, 0.1):
        merger.observe(table, np.array([0, 1]), t)
        assert merger.merge(table, t) == []


def test_tracks_seen_in_one_frame_are_known_apart_for_distinct_s() -> None:
    merger = TrackMerger(distance_m=0.35, after_s=0.5, distinct_s=5.0)
    table = _table([(1.0, 1.0), (3.0, 1.0), (1.2, 1.0)], first_seen=[-5.0, -5.0, -1.0])
    assert [r.tolist() for r in merger.distinct_rows(table, 0.0)] == [[], []]
    merger.observe(table, np.array([0, 1, 2]), 0.0)  # 1 is too far to be confused
    assert [r.tolist() for r in merger.distinct_rows(table, 4.9)] == [[0], [2]]
    table = _table([(1.0, 1.0), (1.2, 1.0)], first_seen=[-5.0, -1.0])
    table.ids = np.array([2, 3])  # track 1 has ended: rows follow the ids
    assert [r.tolist() for r in merger.distinct_rows(table, 4.9)] == [[], []]
    merger.observe(table, np.array([0, 1]), 5.0)
    assert [r.tolist() for r in merger.distinct_rows(table, 9.9)] == [[0], [1]]
    assert [r.tolist() for r in merger.distinct_rows(table, 10.1)] == [[], []]


def test_where_several_sensors_see_a_pair_one_sensors_frames_do_not_prove_two_people() -> None:
    # three sensors detect both tracks; only sensor 2 ever saw them apart (a split blob)
    table = _table([(1.0, 1.0), (1.2, 1.0)], first_seen=[-5.0, -1.0])
    table.sensor_hit_t[:, 0:3] = 1e9
    merger = TrackMerger(distance_m=0.35, after_s=0.5, distinct_sensors=2)
    merged = []
    for t in np.arange(0.0, 1.0, 0.1):
        merger.observe(table, np.array([0, 1]), t, sensor=2)
        merged += merger.merge(table, t)
        assert [r.tolist() for r in merger.distinct_rows(table, t)] == [[], []]
    assert merged == [(0, 1)]
    # a second sensor seeing them apart makes them two people
    merger = TrackMerger(distance_m=0.35, after_s=0.5, distinct_sensors=2)
    for t in np.arange(0.0, 2.0, 0.1):
        merger.observe(table, np.array([0, 1]), t, sensor=2)
        merger.observe(table, np.array([0, 1]), t, sensor=1)
        assert merger.merge(table, t) == []
        assert [r.tolist() for r in merger.distinct_rows(table, t)] == [[0], [1]]
    # with distinct_sensors 1, any one sensor's frame is enough (the rule before)
    merger = TrackMerger(distance_m=0.35, after_s=0.5, distinct_sensors=1)
    for t in np.arange(0.0, 2.0, 0.1):
        merger.observe(table, np.array([0, 1]), t, sensor=2)
        assert merger.merge(table, t) == []
    # a sensor that has not detected both tracks in the last second could not have
    # seen them apart: its silence does not count
    table.sensor_hit_t[:, 0] = -10.0
    table.sensor_hit_t[1, 1] = -10.0  # sensor 1 sees only track 0 (the other hidden)
    merger = TrackMerger(distance_m=0.35, after_s=0.5, distinct_sensors=2)
    for t in np.arange(0.0, 2.0, 0.1):
        merger.observe(table, np.array([0, 1]), t, sensor=2)
        assert merger.merge(table, t) == []


def test_a_second_track_kept_by_one_sensors_split_blob_is_merged() -> None:
    """Sensors a and b start a track each on one person (b's calibration is off); from
    4 s on, every sensor's detections fall on either track in turn (two tracks sharing
    one person's detections), and sensor c splits the person into two blobs, one at each
    track, from 3.5 s to 4.5 s."""

    def confirmed_ids(distinct_sensors: int) -> list[list[int]]:
        config = TrackerConfig(
            estimate_bias=False, adaptive_noise=False, merge_distinct_sensors=distinct_sensors
        )
        tracker = build_tracker(config)
        ids = []
        for k in range(int(12 / FRAME)):
            t = k * FRAME
            x = 1.0 + 0.5 * t
            off = 0.6 if t < 4.0 else 0.3
            turn = t >= 4.0 and k % 2 == 1
            a, b = (x + off, x) if turn else (x, x + off)
            tracker.step(DetectionBatch("a", k, T0 + t, "world", (_det(a, 2.0),)))
            tracker.step(DetectionBatch("b", k, T0 + t + 0.01, "world", (_det(b, 2.0),)))
            split = 3.5 <= t < 4.5
            c = (_det(x, 2.0), _det(x + off, 2.0)) if split else (_det(x + off * (k % 2), 2.0),)
            out = tracker.step(DetectionBatch("c", k, T0 + t + 0.02, "world", c))
            ids.append(sorted(tr.id for tr in out.tracks if tr.confirmed))
        return ids

    at = [int(t / FRAME) for t in (3.0, 4.6, 9.0)]
    ids = confirmed_ids(2)
    assert ids[at[0]] == [1, 2]  # two tracks while a and b disagree by 0.6 m
    assert all(ids[k] == [1] for k in range(at[1], len(ids)))  # merged as the split ends
    # one sensor's frames as proof (the default): two tracks for five seconds more
    assert confirmed_ids(1)[at[2]] == [1, 2]


def test_far_or_differently_moving_tracks_never_merge() -> None:
    merger = TrackMerger(distance_m=0.35, after_s=0.5)
    table = _table([(1.0, 1.0), (1.6, 1.0)], first_seen=[0.0, 0.0])
    assert all(merger.merge(table, t) == [] for t in np.arange(0.0, 2.0, 0.1))
    table = _table([(1.0, 1.0), (1.2, 1.0)], first_seen=[0.0, 0.0])
    table.x[1, 2] = -0.5  # crossing: opposite directions
    assert all(merger.merge(table, t) == [] for t in np.arange(0.0, 2.0, 0.1))


def _det(x: float, y: float) -> Detection:
    return Detection(x=x, y=y, z=1.0, height=1.7, confidence=0.9, distance=3.0)


def test_a_duplicate_track_is_merged_and_the_older_id_kept() -> None:
    """Sensor b starts 0.6 m off (a bad calibration), so it starts a second track."""
    tracker = build_tracker(TrackerConfig(estimate_bias=False, adaptive_noise=False))
    offset = 0.6
    ids_seen = []
    for k in range(int(12 / FRAME)):
        t = k * FRAME
        x = 1.0 + 0.5 * t
        tracker.step(DetectionBatch("a", k, T0 + t, "world", (_det(x, 2.0),)))
        # b's offset shrinks to 0.3 m after 4 s: each sensor keeps feeding its own track,
        # both of them following one person
        off = offset if t < 4.0 else 0.3
        out = tracker.step(DetectionBatch("b", k, T0 + t + 0.01, "world", (_det(x + off, 2.0),)))
        ids_seen.append(sorted(tr.id for tr in out.tracks if tr.confirmed))
    assert [1, 2] in ids_seen  # two tracks while the sensors disagree
    assert ids_seen[-1] == [1]  # one, the older, once they follow one person
    assert tracker.counters["tracks_merged"] == 1
    # merged within a second of coming together (not left to starve for 3 s)
    assert ids_seen[int(5.2 / FRAME)] == [1]


def test_two_people_side_by_side_keep_two_tracks() -> None:
    tracker = build_tracker(TrackerConfig())
    for k in range(int(20 / FRAME)):
        t = k * FRAME
        x = 1.0 + 0.4 * t
        for i, sensor in enumerate("ab"):
            dets = (_det(x, 2.0), _det(x, 2.45))
            out = tracker.step(DetectionBatch(sensor, k, T0 + t + 0.01 * i, "world", dets))
    assert sorted(tr.id for tr in out.tracks if tr.confirmed) == [1, 2]
    assert tracker.counters["tracks_merged"] == 0


def test_a_lost_walker_vouches_for_one_new_track_only() -> None:
    # A walking person's track is lost at t = 0; after it, two tentative tracks start
    # within walking reach: the person's, near where they were last seen, and a split
    # blob or a false positive a little further. Only the nearer is the continuation.
    merger = TrackMerger(distance_m=0.35, reattach_speed_mps=1.5, walking_m=0.3)
    table = _table([(2.0, 1.0), (2.2, 1.0), (2.0, 1.6)], first_seen=[-5.0, 0.5, 0.6])
    table.confirmed = np.array([True, False, False])
    table.last_seen = np.array([0.0, 1.0, 1.0])
    table.recent_xy = np.array([(2.0, 1.0), (2.2, 1.0), (2.0, 1.6)])
    table.birth_xy = table.recent_xy.copy()
    # the lost track's estimate walked 1 m in its last second
    table.hist_t = np.tile(np.linspace(-0.94, 0.0, HISTORY), (3, 1))
    table.hist_xy = np.zeros((3, HISTORY, 2))
    table.hist_xy[0, :, 0] = np.linspace(1.0, 2.0, HISTORY)
    table.hist_xy[0, :, 1] = 1.0
    both_reachable = merger._within_reach(table, np.array([1, 2]), np.array([0]))[0]
    assert both_reachable.all()
    assert merger.continuations(table, 1.0, lost_after_s=0.25).tolist() == [False, True, False]
    # the nearest track out of reach (it started before the loss) leaves the other vouched
    table.first_seen[1] = -1.0
    assert merger.continuations(table, 1.0, lost_after_s=0.25).tolist() == [False, False, True]
    table.first_seen[1] = 0.5
    # a track that was standing still when lost vouches for none
    table.hist_xy[0, :, 0] = 2.0
    assert not merger.continuations(table, 1.0, lost_after_s=0.25).any()


def _noisy_pair(gap: float, noise_var: float, velocity_var: float) -> list[tuple[int, int]]:
    """Merges over 2 s of two tracks ``gap`` apart whose detections had ``noise_var``."""
    merger = TrackMerger(distance_m=0.35, after_s=0.5, max_speed_difference_mps=0.6, gate=9.21)
    table = _table([(1.0, 1.0), (1.0 + gap, 1.0)], first_seen=[-5.0, -1.0])
    table.x[1, 2] += 0.9  # velocities 0.9 m/s apart
    table.cov = np.repeat(np.diag([0.01, 0.01, velocity_var, velocity_var])[None], 2, axis=0)
    noise = np.eye(2)[None] * noise_var
    merger.observe(table, np.array([0]), -0.1, noise)  # each fed alone: not known apart
    merger.observe(table, np.array([1]), -0.1, noise)
    return sorted({p for t in np.arange(0.0, 2.0, 0.1) for p in merger.merge(table, t)})


def test_the_merge_distance_and_speed_widen_with_the_tracks_noise() -> None:
    # sqrt(9.21 * 2 * 0.04) = 0.86 m and sqrt(9.21 * 2 * 0.05) = 0.96 m/s
    assert _noisy_pair(0.7, noise_var=0.04, velocity_var=0.05) == [(0, 1)]
    # quiet detections: 0.7 m and 0.9 m/s apart are two people
    assert _noisy_pair(0.7, noise_var=0.004, velocity_var=0.05) == []
    assert _noisy_pair(0.7, noise_var=0.04, velocity_var=0.01) == []
    assert _noisy_pair(0.9, noise_var=0.04, velocity_var=0.05) == []  # beyond 0.86 m


def _one_noisy_walker(sigma_m: float, seed: int, merge_by_noise: bool = True) -> list[int]:
    """Published tracks per frame: one person walking at 0.5 m/s for 12 s, seen by three
    sensors at 30 Hz whose detections scatter ``sigma_m`` per axis (white)."""
    rng = np.random.default_rng(seed)
    tracker = build_tracker(TrackerConfig(merge_by_noise=merge_by_noise))
    counts = []
    for k in range(int(12.0 / FRAME)):
        t = k * FRAME
        for s, sensor in enumerate(("a", "b", "c")):
            x, y = -3.0 + 0.5 * t + rng.normal(0.0, sigma_m), rng.normal(0.0, sigma_m)
            d = Detection(x=x, y=y, z=1.0, height=1.75, confidence=0.9, distance=3.0)
            batch = DetectionBatch(
                sensor_id=sensor, seq=k, stamp=T0 + t + s * FRAME / 3, frame_id="world",
                detections=(d,),
            )  # fmt: skip
            out = tracker.step(batch)
        if t >= 4.0:
            counts.append(len(out.tracks))
    return counts


def test_one_walker_seen_by_three_sensors_with_modest_noise_has_one_track() -> None:
    counts = _one_noisy_walker(0.12, seed=0)
    assert np.mean(np.array(counts) == 1) >= 0.95


def test_one_walker_seen_by_three_sensors_with_large_noise_has_one_track() -> None:
    # the sensors' noise is learned beside the tentative tracks the noise starts, and two
    # tracks of the person are merged within what that noise explains
    counts = _one_noisy_walker(0.25, seed=0)
    assert np.mean(np.array(counts) == 1) >= 0.95
    off = _one_noisy_walker(0.25, seed=0, merge_by_noise=False)
    assert np.mean(np.array(off) == 1) < 0.8


def _two_noisy_walkers(sigma_m: float, seed: int, unambiguous: bool) -> list[int]:
    """Published tracks per frame: two people walking side by side 0.7 m apart."""
    rng = np.random.default_rng(seed)
    tracker = build_tracker(TrackerConfig(merge_proof_unambiguous=unambiguous))
    counts = []
    for k in range(int(12.0 / FRAME)):
        t = k * FRAME
        for s, sensor in enumerate(("a", "b", "c")):
            xy = np.array([[-3.0 + 0.5 * t, 0.0], [-3.0 + 0.5 * t, 0.7]])
            xy += rng.normal(0.0, sigma_m, xy.shape)
            dets = tuple(
                Detection(x=x, y=y, z=1.0, height=1.75, confidence=0.9, distance=3.0)
                for x, y in xy.tolist()
            )
            batch = DetectionBatch(
                sensor_id=sensor, seq=k, stamp=T0 + t + s * FRAME / 3, frame_id="world",
                detections=dets,
            )  # fmt: skip
            out = tracker.step(batch)
        if t >= 4.0:
            counts.append(len(out.tracks))
    return counts


@pytest.mark.xfail(
    strict=True,
    reason="known limitation of merge_proof_unambiguous off: at 0.25 m of noise per axis, "
    "two people 0.7 m apart get four tracks in their first two seconds (before the noise "
    "is learned); each sensor frame has two detections, so every pair of those tracks is "
    "once detected in one frame, counts as two people and is never merged "
    "(docs/evaluation.md; with the option, the default, they are shed: the test below)",
)
def test_two_walkers_side_by_side_with_large_noise_have_two_tracks_by_the_older_rule() -> None:
    counts = _two_noisy_walkers(0.25, seed=0, unambiguous=False)
    assert np.mean(np.array(counts) == 2) >= 0.95


def test_only_the_rows_a_frame_proves_apart_block_a_merge() -> None:
    merger = TrackMerger(distance_m=0.35, after_s=0.5)
    table = _table([(1.0, 1.0), (1.2, 1.0)], first_seen=[-5.0, -1.0])
    merged = []
    for t in np.arange(0.0, 2.0, 0.1):
        merger.observe(table, np.array([0, 1]), t, apart=np.array([True, False]))
        # detected together: kept a body's depth apart, but not proven two people
        assert [r.tolist() for r in merger.distinct_rows(table, t)] == [[0], [1]]
        merged += merger.merge(table, t)
    assert merged and set(merged) == {(0, 1)}  # the table is not changed here
    proven = TrackMerger(distance_m=0.35, after_s=0.5)
    for t in np.arange(0.0, 2.0, 0.1):
        proven.observe(table, np.array([0, 1]), t, apart=np.array([True, True]))
        assert proven.merge(table, t) == []
    assert [r.tolist() for r in proven.distinct_rows(table, 2.0)] == [[0], [1]]
    assert [r.tolist() for r in merger.distinct_rows(table, 7.0)] == [[], []]  # lapsed


def test_unambiguous_proof_lets_two_noisy_walkers_shed_their_extra_tracks() -> None:
    # the tracks started before the noise was learned take each other's detections in
    # overlapping gates; by the older rule every such frame proves two people
    last = 2.0 / FRAME  # the last 2 s of each run
    on = [
        np.array(_two_noisy_walkers(0.25, seed, unambiguous=True))[-int(last) :]
        for seed in range(4)
    ]
    off = [
        np.array(_two_noisy_walkers(0.25, seed, unambiguous=False))[-int(last) :]
        for seed in range(4)
    ]
    assert sum(np.mean(c == 2) >= 0.9 for c in on) >= 3  # 0.95, 0, 1 and 1
    assert min(c.min() for c in on) >= 2  # the two people are never merged into one
    assert max(np.mean(c == 2) for c in off) <= 0.1


def test_a_snapshot_from_before_the_tracks_noise_was_kept_restores() -> None:
    merger = TrackMerger(gate=9.21)
    merger.restore(({(1, 2): 0.0}, {(1, 2): 0.0}, {}))  # a checkpoint of the older form
    assert merger.snapshot() == ({(1, 2): 0.0}, {(1, 2): 0.0}, {}, {}, {}, {})


def test_a_snapshot_from_before_the_sensors_seeing_a_pair_apart_were_kept_restores() -> None:
    # its pairs seen apart name no sensor: each counts as seen apart by one
    merger = TrackMerger(distinct_sensors=2)
    merger.restore(({}, {}, {(1, 2): 3.0}, {}))
    assert merger.snapshot()[2] == {(1, 2): 3.0}
    assert merger.snapshot()[4] == {(1, 2): {-1: 3.0}}
    table = _table([(1.0, 1.0), (1.2, 1.0)], first_seen=[-5.0, -1.0])
    assert [r.tolist() for r in merger.distinct_rows(table, 4.0)] == [[0], [1]]
    assert [r.tolist() for r in merger.distinct_rows(table, 8.5)] == [[], []]


def test_a_snapshot_from_before_the_pairs_detected_together_were_kept_restores() -> None:
    merger = TrackMerger()
    merger.restore(({}, {}, {(1, 2): 3.0}, {}, {}))
    assert merger.snapshot()[5] == {}
    merger.observe(
        _table([(1.0, 1.0), (1.2, 1.0)], first_seen=[-5.0, -1.0]),
        np.array([0, 1]),
        4.0,
        apart=np.array([False, True]),
    )
    assert merger.snapshot()[5] == {(1, 2): 4.0}
