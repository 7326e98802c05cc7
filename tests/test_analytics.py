"""Analytics: oracles on known paths, places, recordings, the report in a real browser,
and the classroom against ground truth."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from openptrack_py.analytics import PeopleFrame, ZoneTracker, analyze, frames_from_recording
from openptrack_py.analytics.people import ThinnedSeries, convex_hull, polygon_area
from openptrack_py.analytics.report import SECTIONS, write_report
from openptrack_py.config import DoorConfig, ZoneConfig
from openptrack_py.messages import Track, TrackBatch
from openptrack_py.messages.codec import encode_track_batch
from openptrack_py.recordings import open_writer
from tests.conftest import wait_for

T0 = 1_764_000_000.0
RATE = 10.0


def _square_walk(loops: int, side: float = 2.0, speed: float = 1.0) -> np.ndarray:
    """``t, x, y`` of one person walking round a square (corner at the origin)."""
    perimeter = 4 * side
    t = np.arange(0.0, loops * perimeter / speed, 1.0 / RATE)
    s = (t * speed) % perimeter
    x = np.clip(s, 0, side) - np.clip(s - 2 * side, 0, side)
    y = np.clip(s - side, 0, side) - np.clip(s - 3 * side, 0, side)
    return np.column_stack([T0 + t, x, y])


def _frames(*people: np.ndarray) -> list[PeopleFrame]:
    """Frames of several people's ``t, x, y`` arrays (the same times)."""
    return [
        PeopleFrame(float(people[0][i, 0]), {k + 1: (float(p[i, 1]), float(p[i, 2]))
                                             for k, p in enumerate(people)})
        for i in range(len(people[0]))
    ]  # fmt: skip


def _circle_walk(seconds: float, radius: float = 3.0, speed: float = 1.0) -> np.ndarray:
    t = np.arange(0.0, seconds, 1.0 / RATE)
    angle = t * speed / radius
    return np.column_stack([T0 + t, radius * np.cos(angle), radius * np.sin(angle)])


@pytest.mark.parametrize("offered", [1, 7, 8, 9, 100, 1000, 12345])
def test_a_thinned_series_keeps_at_most_its_capacity_evenly_spread(offered: int) -> None:
    series = ThinnedSeries(8, 2)
    for i in range(offered):
        series.offer(float(i), 2.0 * i)
    rows = series.array()
    assert 1 <= len(rows) <= 8 and rows[0, 0] == 0.0
    assert np.all(np.diff(rows[:, 0]) == series.every)  # every kept row, equally spaced
    assert offered - 1 - rows[-1, 0] < series.every  # the latest kept is recent
    assert offered <= 8 or len(rows) >= 4  # thinning never drops below half
    np.testing.assert_array_equal(rows[:, 1], 2.0 * rows[:, 0])


def test_a_known_walk_gives_its_length_area_and_speed() -> None:
    walk = _circle_walk(60.0)  # 60 m round a 3 m circle, three times and a bit
    person = analyze(_frames(walk)).people[1]
    # averaging over 1 s and 1 s steps cut a 3 m circle's curve by about 1 %
    assert person.length_m == pytest.approx(60.0, rel=0.02)
    assert person.bbox_area_m2 == pytest.approx(36.0, rel=0.03)
    assert person.hull_area_m2 == pytest.approx(math.pi * 9, rel=0.03)
    assert person.mean_speed_mps == pytest.approx(1.0, rel=0.02)
    assert person.seen_s == pytest.approx(60.0, abs=0.2)
    assert person.momentum[-1][1] == pytest.approx(person.length_m)
    assert [round(m[1]) for m in person.momentum[:3]] == [0, 4, 9]  # every 5 s, whole steps


def test_sharp_corners_are_cut_by_the_averaging_the_jitter_needs() -> None:
    """The price of smoothing, stated: a 2 m square walked at 1 m/s measures ~18 % short."""
    person = analyze(_frames(_square_walk(loops=5))).people[1]
    assert 0.78 * 40 < person.length_m < 0.88 * 40


def test_standing_still_with_tracker_jitter_is_not_walking() -> None:
    rng = np.random.default_rng(0)
    t = T0 + np.arange(0, 60, 1 / RATE)
    still = np.column_stack([t, 3 + rng.normal(0, 0.05, len(t)), 2 + rng.normal(0, 0.05, len(t))])
    person = analyze(_frames(still)).people[1]
    assert person.length_m < 3.0  # unsmoothed 10 Hz positions would give ~40 m
    assert person.density_area_m2 <= 0.5


def test_relative_distance_mean_and_spread() -> None:
    walk = _square_walk(loops=2)
    beside = walk.copy()
    beside[:, 1] += 1.5
    pair = analyze(_frames(walk, beside)).pairs[(1, 2)]
    assert pair.mean_m == pytest.approx(1.5, abs=1e-9)
    assert pair.std_m == pytest.approx(0.0, abs=1e-6)
    assert pair.together_s == pytest.approx(16.0, abs=0.2)
    # a distance that is 1 m half the time and 3 m the other half: mean 2, std 1
    near, far = walk.copy(), walk.copy()
    far[:, 1] += np.where(np.arange(len(walk)) % 2 == 0, 1.0, 3.0)
    pair = analyze(_frames(near, far)).pairs[(1, 2)]
    assert (pair.mean_m, pair.std_m) == pytest.approx((2.0, 1.0), abs=0.01)


def test_hull_and_area_oracles() -> None:
    pts = np.array([(0, 0), (2, 0), (2, 1), (0, 1), (1, 0.5), (1, 0.2)], dtype=float)
    assert polygon_area(convex_hull(pts)) == pytest.approx(2.0)
    assert len(convex_hull(pts)) == 4


ZONE = ZoneConfig(name="stage", polygon=[(1.0, -1.0), (3.0, -1.0), (3.0, 1.0), (1.0, 1.0)])
DOOR = DoorConfig(name="door", a=(0.5, -1.0), b=(0.5, 1.0))  # walking +x crosses it right to left


def test_zones_count_entries_and_dwell_and_doors_count_the_way_people_cross() -> None:
    t = T0 + np.arange(0, 10, 1 / RATE)
    x = np.where(t - T0 < 5, t - T0, 10 - (t - T0))  # out to x = 5 and back
    person = np.column_stack([t, x, np.zeros_like(t)])
    result = analyze(_frames(person), zones=[ZONE], doors=[DOOR])
    zone, door = result.zones[0], result.doors[0]
    assert zone.entries == 2  # on the way out and on the way back
    assert zone.dwell_s[1] == pytest.approx(4.0, abs=0.25)  # 1 <= x <= 3: 2 s each way
    assert (door.entries, door.exits) == (1, 1)


def test_a_person_briefly_unseen_does_not_leave_the_zone() -> None:
    zones = ZoneTracker([ZONE], hold_s=1.0)
    assert zones.update(T0, {7: (2.0, 0.0)}) == ([(7, "stage")], [])
    assert zones.update(T0 + 0.5, {}) == ([], [])  # a dropped track, not a departure
    assert zones.update(T0 + 0.6, {7: (2.1, 0.0)}) == ([], [])
    assert zones.update(T0 + 2.0, {}) == ([], [(7, "stage")])
    assert zones.counts() == {"stage": 0}


def _recording(path: Path) -> None:
    writer = open_writer(path)
    walk = _square_walk(loops=1)
    for i, (t, x, y) in enumerate(walk.tolist()):
        tracks = (
            Track(id=3, x=x, y=y, z=0.9, height=1.7, vx=0, vy=0, age=i / RATE,
                  confidence=0.9, visibility=1, stable_id=10003, identity="Ada"),
            Track(id=4, x=x + 2, y=y, z=0.9, height=1.7, vx=0, vy=0, age=i / RATE,
                  confidence=0.9, visibility=1),
        )  # fmt: skip
        for k in range(3):  # a tracker publishes after every sensor's batch
            batch = TrackBatch(t + k / 90, i * 3 + k, "world", tracks, (3, 4), 4)
            writer.write(t + k / 90 + 0.01, "opt/default/tracks", encode_track_batch(batch))
    writer.close()


def test_a_recording_is_read_at_the_analysis_rate_with_stable_ids_and_names(
    tmp_path: Path,
) -> None:
    path = tmp_path / "run.mcap"
    _recording(path)
    recording, frames = frames_from_recording(path, rate_hz=RATE)
    frames = list(frames)
    assert recording.stopped is None
    assert len(frames) == pytest.approx(80, abs=1)  # 8 s at 10 Hz, not 30 Hz
    result = analyze(frames)
    assert set(result.people) == {10003, 4}
    assert result.people[10003].name == "Ada" and result.label(10003) == "Ada (10003)"
    assert result.pairs[(4, 10003)].mean_m == pytest.approx(2.0)


CHROMIUM_TESTS = pytest.importorskip("tests.test_web")


@pytest.mark.skipif(CHROMIUM_TESTS.CHROMIUM is None, reason="Debian's chromium is not installed")
def test_the_report_renders_every_section_in_headless_chromium(tmp_path: Path) -> None:
    walk = _square_walk(loops=2)
    other = walk.copy()
    other[:, 1:] = other[:, 1:] * 0.5 + 3.0
    analysis = analyze(_frames(walk, other), zones=[ZONE], doors=[DOOR])
    report = write_report(analysis, tmp_path / "report.html", source="test")
    url = report.resolve().as_uri()
    browser = CHROMIUM_TESTS.Chromium(url, tmp_path / "profile", tmp_path / "chromium.log")
    try:
        browser.attach_to_page(url)
        browser.call("Runtime.enable")
        browser.call("Log.enable")
        browser.call("Page.reload", {"ignoreCache": True})
        state = """JSON.stringify({
            ready: document.readyState,
            sections: [...document.querySelectorAll("section")].map(s => s.id),
            images: [...document.images].map(i => i.complete && i.naturalWidth > 0),
            people: document.querySelectorAll("#people tbody tr").length})"""
        seen: dict = {}

        def loaded() -> bool:
            text = browser.evaluate(state)
            seen.update(json.loads(text) if text else {})
            return seen.get("ready") == "complete" and all(seen.get("images") or [False])

        wait_for(loaded, 20, "the report with every plot loaded")
    finally:
        browser.close()
    assert seen["sections"] == [sid for sid, _ in SECTIONS]
    assert len(seen["images"]) >= 7 and seen["people"] == 2
    assert not browser.page_errors(), browser.page_errors()


@pytest.mark.slow
def test_classroom_analytics_against_ground_truth() -> None:
    """Realistic profile, seed 41 (not looked at while the analytics were written), the
    whole lesson (170 s): every person's trajectory length within 5 %, motion area within
    10 %, mean distance of every pair within 0.05 m of the ground truth's."""
    from openptrack_py.eval.analytics_check import check_analytics
    from openptrack_py.sim.scenarios import build_scenario

    check = check_analytics(build_scenario("classroom", seed=41, profile="realistic"))
    lengths = np.array(list(check.length_errors().values()))
    areas = np.array(list(check.area_errors().values()))
    distances = np.array(list(check.distance_errors().values()))
    assert len(lengths) >= 15 and len(distances) >= 100
    assert np.abs(lengths).max() <= 0.05, lengths
    assert np.abs(areas).max() <= 0.10, areas
    assert np.abs(distances).max() <= 0.05, distances
    assert math.isfinite(check.result.metrics.mota)


def test_analyze_and_replay_read_a_cut_recording_up_to_the_cut_and_say_where(
    tmp_path: Path,
) -> None:
    import subprocess
    import sys

    from tests.conftest import python_env

    whole = tmp_path / "whole.mcap"
    writer = open_writer(whole, flush_every_s=0.0)
    for i, (t, x, y) in enumerate(_square_walk(loops=3).tolist()):
        track = Track(id=1, x=x, y=y, z=0.9, height=1.7, vx=0, vy=0, age=i / RATE,
                      confidence=0.9, visibility=1)  # fmt: skip
        batch = TrackBatch(t, i, "world", (track,), (1,), 1)
        writer.write(t, "opt/default/tracks", encode_track_batch(batch))
    writer.close()
    cut = tmp_path / "cut.mcap"
    data = whole.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    done = subprocess.run(
        [sys.executable, "-m", "openptrack_py.cli", "analyze", str(cut), "--format", "json"],
        capture_output=True, text=True, env=python_env(), timeout=60,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert f"{cut}: " in done.stderr and ("cut" in done.stderr or "corrupt" in done.stderr)
    seen = json.loads(done.stdout)[0]["seen_s"]
    assert 0.3 * 24 < seen < 0.7 * 24  # about half of the 24 s walked
    done = subprocess.run(
        [sys.executable, "-m", "openptrack_py.cli", "replay", str(cut), "--topics", "tracks",
         "--speed", "100", "-e", "tcp/127.0.0.1:9", "--no-multicast-scouting"],
        capture_output=True, text=True, env=python_env(), timeout=60,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert f"{cut}: " in done.stderr and "replayed" in done.stdout
