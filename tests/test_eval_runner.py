"""Oracle tests of the evaluation harness: scenario -> hypotheses -> CLEAR MOT / IDF1."""

from __future__ import annotations

import inspect
import json
from dataclasses import dataclass, field

import numpy as np
import pytest

from openptrack_py.config import TrackerConfig
from openptrack_py.errors import ConfigError
from openptrack_py.eval.oracle import TruthFeed
from openptrack_py.eval.reach import SensorReach
from openptrack_py.eval.runner import Hypotheses, TrackerFeed, evaluate
from openptrack_py.eval.trackers import tracking_feed
from openptrack_py.messages import DetectionBatch, GroundTruthFrame, Track, TrackBatch
from openptrack_py.sim import DEFAULT_START_TIME, build_scenario
from openptrack_py.sim.simulator import SensorFrame, TruthFrame
from openptrack_py.tracking import TrackingPipeline


def _truth(**faults: object) -> TruthFeed:
    return TruthFeed(start_time=DEFAULT_START_TIME, **faults)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def crowd():
    return build_scenario("crowd", seed=4, duration_s=20.0)


def test_ground_truth_scores_perfectly(crowd) -> None:
    m = evaluate(crowd, _truth()).metrics
    assert (m.mota, m.idf1, m.motp) == (1.0, 1.0, 0.0)
    assert m.id_switches == m.fp == m.fn == m.fragmentations == m.duplicates == 0
    assert m.frames == 601 and m.gt_tracks == 7


def test_one_relabelled_person_is_exactly_one_id_switch(crowd) -> None:
    m = evaluate(crowd, _truth(relabel=(3, 10.0))).metrics
    assert m.id_switches == 1 and m.fp == 0 and m.fn == 0
    assert m.mota == pytest.approx(1 - 1 / m.gt_objects)
    # person 3 has its first id in frames 0..299 and the new one in 300..600: IDF1 keeps the
    # longer run (301 frames) and loses the 300 others, once as IDFP and once as IDFN
    assert m.idf1 == pytest.approx(1 - 300 / m.gt_objects, abs=1e-12)


def test_two_people_exchanging_ids_are_two_switches(crowd) -> None:
    m = evaluate(crowd, _truth(swap=(1, 2, 5.0))).metrics
    assert m.id_switches == 2 and m.fp == m.fn == 0


@dataclass
class Doubled:
    """The truth, with a second track following one person for a while."""

    person: int
    start: float
    end: float
    truth: TruthFeed = field(default_factory=lambda: _truth())

    def on_sensor_frame(self, frame: SensorFrame) -> None:
        """Sensors are ignored."""

    def on_truth_frame(self, frame: TruthFrame) -> None:
        self.truth.on_truth_frame(frame)

    def hypotheses_at(self, t: float) -> Hypotheses | None:
        hyp = self.truth.hypotheses_at(t)
        assert hyp is not None
        if not self.start <= t - DEFAULT_START_TIME <= self.end:
            return hyp
        (row,) = np.flatnonzero(hyp.ids == self.person)
        twin = hyp.xy[row] + [0.15, 0.1]
        return Hypotheses(np.r_[hyp.ids, 99], np.vstack([hyp.xy, twin]))


def test_a_second_track_on_one_person_is_one_duplicate_with_its_duration(crowd) -> None:
    m = evaluate(crowd, Doubled(person=3, start=5.0, end=8.0)).metrics
    assert m.duplicates == 1 and m.duplicate_s == pytest.approx(3.0, abs=1e-6)
    assert m.fp == 91 and m.id_switches == 0
    assert evaluate(crowd, Doubled(person=3, start=5.0, end=5.9)).metrics.duplicates == 0


def test_frames_without_output_count_every_object_as_missed(crowd) -> None:
    missing: list[int] = []

    def on_frame(t: float, truth: GroundTruthFrame, hyp: Hypotheses | None) -> None:
        if hyp is None:
            missing.append(sum(p.covered for p in truth.people))

    m = evaluate(crowd, _truth(drop=(5.0, 6.0)), on_frame=on_frame).metrics
    assert len(missing) == 30  # one second at 30 Hz
    assert m.fn == sum(missing) and m.fp == 0 and m.id_switches == 0
    assert m.mota == pytest.approx(1 - sum(missing) / m.gt_objects)


def test_people_out_of_every_view_are_dont_care() -> None:
    # In "distance" people walk beyond the sensor's 10 m range: not covered. The oracle
    # still reports them; that must cost nothing (no FP), and they are not objects (no FN).
    scenario = build_scenario("distance", seed=0, duration_s=40.0)
    uncovered = []

    def on_frame(t: float, truth: GroundTruthFrame, hyp: Hypotheses | None) -> None:
        uncovered.append(sum(not p.covered for p in truth.people))

    m = evaluate(scenario, _truth(), on_frame=on_frame).metrics
    assert sum(uncovered) > 0, "scenario should take someone out of coverage"
    assert m.fp == 0 and m.fn == 0 and m.mota == 1.0
    assert m.gt_objects == 2 * len(uncovered) - sum(uncovered)


def test_warmup_frames_are_not_scored(crowd) -> None:
    m = evaluate(crowd, _truth(drop=(0.0, 2.0)), warmup_s=2.0).metrics
    assert m.fn == 0 and m.frames == 601 - 60


@dataclass
class FixedTracker:
    """Reports one track at a fixed place moving at a fixed velocity."""

    x: float
    vx: float
    steps: list[float] = field(default_factory=list)
    time: float | None = None

    def step(self, batch: DetectionBatch) -> TrackBatch:
        self.steps.append(batch.stamp)
        track = Track(
            id=1, x=self.x, y=0.0, z=0.9, height=1.7, vx=self.vx, vy=0.0, age=1.0, confidence=1.0
        )
        return TrackBatch(stamp=batch.stamp, seq=len(self.steps), tracks=(track,), max_id=1)


def _frame(capture: float, offset: float = 0.0) -> SensorFrame:
    batch = DetectionBatch("k1", 0, capture + offset, "world", ())
    return SensorFrame(capture + 0.03, capture, batch, ())


def _feed(tracker: FixedTracker, stale_after_s: float = 1.0) -> TrackerFeed:
    pipeline = TrackingPipeline(tracker, window_s=0.0, clock_correction="none")  # type: ignore[arg-type]
    return TrackerFeed(pipeline, stale_after_s=stale_after_s)


def test_tracker_output_is_extrapolated_to_the_truth_time() -> None:
    feed = _feed(FixedTracker(x=1.0, vx=2.0), stale_after_s=1.0)
    assert feed.hypotheses_at(100.0) is None  # nothing yet
    feed.on_sensor_frame(_frame(100.0))
    hyp = feed.hypotheses_at(100.25)
    assert hyp is not None
    np.testing.assert_allclose(hyp.xy, [[1.5, 0.0]])
    assert feed.hypotheses_at(101.5) is None  # older than stale_after_s: a missing frame


def test_sensor_clock_offsets_do_not_shift_the_evaluation() -> None:
    # A sensor 0.15 s ahead writes stamps 0.15 s late; the feed maps them back to true time.
    feed = _feed(FixedTracker(x=0.0, vx=1.0))
    feed.on_sensor_frame(_frame(200.0, offset=0.15))
    hyp = feed.hypotheses_at(200.5)
    assert hyp is not None
    np.testing.assert_allclose(hyp.xy, [[0.5, 0.0]])


def test_evaluate_needs_a_finite_scenario() -> None:
    with pytest.raises(ValueError, match="finite duration"):
        evaluate(build_scenario("crowd", duration_s=None), _truth())


@pytest.mark.slow
def test_rgbd_evaluation_tracks_through_the_real_detector_children_included() -> None:
    """Rendered sensors and the real detector in the loop: visitors, a child among them."""
    from openptrack_py.eval.trackers import run_eval

    scenario = build_scenario("installation", seed=0, duration_s=12.0)
    scores = run_eval(scenario, sensor_model="rgbd").to_dict()
    # visitors are confirmed once they have walked 0.5 m: a second or so of the 12 s
    assert scores["mota"] >= 0.85 and scores["idf1"] >= 0.85, scores
    assert scores["id_switches"] == 0


# -------------------------------------------------------------- simulator noise profiles

HAS_PROFILES = "profile" in inspect.signature(build_scenario).parameters


def _recording_build(monkeypatch: pytest.MonkeyPatch, with_profiles: bool) -> list[dict]:
    """Replace the simulator's scenario builder by one that records its keyword arguments
    (and takes ``profile`` or not), building a short real scenario."""
    import openptrack_py.eval.trackers as trackers

    calls: list[dict] = []

    def build(name: str, seed: int = 0, duration_s: float | None = -1.0, **kw: object):
        calls.append(kw)
        return build_scenario(name, seed=seed, duration_s=2.0)

    def build_with_profiles(
        name: str, seed: int = 0, duration_s: float | None = -1.0, profile: str | None = None
    ):
        return build(name, seed, duration_s, **({} if profile is None else {"profile": profile}))

    monkeypatch.setattr(
        trackers, "build_scenario", build_with_profiles if with_profiles else build
    )
    return calls


def test_run_eval_passes_a_profile_only_when_given(monkeypatch: pytest.MonkeyPatch) -> None:
    from openptrack_py.eval.trackers import run_eval

    calls = _recording_build(monkeypatch, with_profiles=True)
    run_eval("crowd", tracker="truth", profile="harsh")
    run_eval("crowd", tracker="truth")
    assert calls == [{"profile": "harsh"}, {}]


@pytest.mark.parametrize(
    "with_profiles, passed", [(True, [{"profile": "realistic"}]), (False, [{}])]
)
def test_the_cli_evaluates_on_realistic_by_default_where_there_are_profiles(
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    with_profiles: bool,
    passed: list[dict],
) -> None:
    from openptrack_py.cli import main

    calls = _recording_build(monkeypatch, with_profiles)
    assert main(["eval", "--tracker", "truth", "--format", "json"]) == 0
    row = json.loads(capsys.readouterr().out)
    assert calls == passed and row.get("profile") == passed[0].get("profile")


def test_a_profile_the_simulator_lacks_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    from openptrack_py.eval.trackers import run_eval

    _recording_build(monkeypatch, with_profiles=False)
    with pytest.raises(ConfigError, match="no noise profiles"):
        run_eval("crowd", tracker="truth", profile="harsh")


@pytest.mark.skipif(not HAS_PROFILES, reason="the simulator has no noise profiles yet")
@pytest.mark.parametrize("profile", ["ideal", "realistic", "harsh"])
def test_every_profile_reaches_the_simulator(profile: str) -> None:
    from openptrack_py.eval.trackers import run_eval

    m = run_eval("crowd", duration_s=3.0, tracker="truth", profile=profile).metrics
    assert m.mota == 1.0 and m.duplicates == 0


def test_a_person_counts_as_seen_for_a_second_after_a_detection() -> None:
    reach = SensorReach(window_s=1.0)
    assert reach.share() is None
    reach.on_detections(0.0, (7, 0))  # 0: clutter, nobody
    reach.on_truth(0.5, [7, 8])  # 7 seen 0.5 s ago, 8 never
    reach.on_truth(1.0, [7])  # exactly the window
    reach.on_truth(1.5, [7])  # 1.5 s ago
    assert (reach.covered, reach.seen) == (4, 2)
    assert reach.share() == 0.5


def test_hidden_people_cap_what_a_tracker_scores_but_not_the_oracle() -> None:
    # "occlusions": two people walk behind cabinets, in view but hidden from the sensor
    occluded = build_scenario("occlusions", seed=3, duration_s=40.0, profile="realistic")
    crowd = build_scenario("crowd", seed=4, duration_s=20.0, profile="realistic")
    oracle = evaluate(occluded, _truth()).to_dict()
    tracked = evaluate(occluded, tracking_feed(TrackerConfig())).to_dict()
    assert oracle["seen"] == tracked["seen"] < 0.8  # the sensors' figure, not the feed's
    assert oracle["mota"] == oracle["idf1"] == 1.0  # the oracle knows where hidden people are
    assert tracked["mota"] <= tracked["seen"] + 0.02
    assert tracked["idf1"] <= tracked["idf1_seen"] + 0.02
    assert evaluate(crowd, _truth()).to_dict()["seen"] > 0.97
