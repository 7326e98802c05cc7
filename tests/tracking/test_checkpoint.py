"""Checkpoints: the tracker's state on disk, ids never reused, tracks resumed."""

from __future__ import annotations

import stat
from pathlib import Path

from openptrack_py.config import TrackerConfig
from openptrack_py.tracking import build_tracker
from openptrack_py.tracking.checkpoint import ID_BLOCK, CheckpointStore, resume_ids, resume_tracks
from tests.tracking.helpers import FRAME, T0, det, make_batch

STILL = {"confirm_min_displacement_m": 0.0, "confirm_min_age_s": 0.0}


def _walker(tracker, start: float, frames: int, x0: float = 1.0) -> float:
    t = start
    for k in range(frames):
        t = start + k * FRAME
        tracker.step(make_batch(t, [det(x0 + 0.8 * (t - start), 2.0)], seq=k))
    return t


def test_a_checkpoint_round_trips_the_tracks_and_reserves_ids(tmp_path: Path) -> None:
    store = CheckpointStore(tmp_path / "state" / "tracker.ckpt")
    tracker = build_tracker(TrackerConfig(**STILL))
    _walker(tracker, T0, 30)
    store.save(tracker)
    assert stat.S_IMODE((tmp_path / "state").stat().st_mode) == 0o700
    ckpt = CheckpointStore(store.path).load()
    assert ckpt is not None and ckpt.table.ids.tolist() == tracker.table.ids.tolist()
    assert ckpt.reserved_id == tracker.max_id + ID_BLOCK


def test_ids_continue_above_the_reservation_after_a_crash(tmp_path: Path) -> None:
    """Ids given out after the last checkpoint are never given again."""
    store = CheckpointStore(tmp_path / "tracker.ckpt")
    first = build_tracker(TrackerConfig(**STILL))
    _walker(first, T0, 10)
    store.save(first)
    for k in range(50):  # ids given out after the checkpoint, then a crash
        first.step(make_batch(T0 + 1 + k, [det(9.0 + 3 * (k % 2), 9.0)]))
    assert first.max_id > 1
    second = build_tracker(TrackerConfig(**STILL))
    ckpt = CheckpointStore(store.path).load()
    assert ckpt is not None
    resume_ids(second, ckpt)  # an old checkpoint: only the ids resume
    _walker(second, T0 + 100, 10)
    assert second.table.ids.min() > first.max_id


def test_a_recent_checkpoint_resumes_its_tracks_with_their_ids(tmp_path: Path) -> None:
    store = CheckpointStore(tmp_path / "tracker.ckpt")
    first = build_tracker(TrackerConfig(**STILL))
    last = _walker(first, T0, 60)
    confirmed = first.table.ids[first.table.confirmed].tolist()
    assert confirmed
    store.save(first)
    ckpt = CheckpointStore(store.path).load()
    assert ckpt is not None
    second = build_tracker(TrackerConfig(**STILL))
    resume_ids(second, ckpt)
    assert resume_tracks(second, ckpt, last + 3.0) == len(first.table)
    # 3 s later the person, who walked on, is seen again: same id
    x = 1.0 + 0.8 * (last + 3.0 - T0)
    out = None
    for k in range(10):
        out = second.step(make_batch(last + 3.0 + k * FRAME, [det(x + 0.8 * k * FRAME, 2.0)]))
    assert out is not None and [t.id for t in out.tracks] == confirmed


def test_resumed_tracks_keep_each_sensors_column(tmp_path: Path) -> None:
    # before the restart sensor "b" came first; after it "a" does: the resumed tracks'
    # per-sensor columns (support, sightings) still belong to the same sensors
    store = CheckpointStore(tmp_path / "tracker.ckpt")
    first = build_tracker(TrackerConfig(**STILL))
    for k in range(30):
        for i, sensor in enumerate(("b", "a")):
            first.step(make_batch(T0 + k * FRAME + 0.01 * i, [det(1.0, 2.0)], sensor, k))
    store.save(first)
    ckpt = CheckpointStore(store.path).load()
    assert ckpt is not None and ckpt.sensors == ("b", "a")
    second = build_tracker(TrackerConfig(**STILL))
    resume_tracks(second, ckpt, T0 + 1.5)
    before = second.table.sensor_hit_t.copy()
    second.step(make_batch(T0 + 1.5 + FRAME, [det(1.0, 2.0)], "a", 30))
    changed = (second.table.sensor_hit_t != before).any(axis=0)
    assert changed.nonzero()[0].tolist() == [1]


def test_an_unreadable_checkpoint_is_ignored(tmp_path: Path) -> None:
    path = tmp_path / "tracker.ckpt"
    path.write_bytes(b"not a checkpoint")
    assert CheckpointStore(path).load() is None
    assert CheckpointStore(tmp_path / "missing.ckpt").load() is None
