"""Noise profiles: ``ideal`` is the old simulator bit for bit; ``realistic`` really is.

``realistic`` is checked against the outside evidence it is calibrated from (the
childcare paper's 0.10 m mean / 0.08 m standard deviation of single-frame detection
error) and for each of its mechanisms: persistent per-person error, off-centre detections
of half-hidden people, decoys recurring at one place for every sensor, calibration
offsets, transient confident false positives, persistent splits, merges.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from collections import defaultdict

import numpy as np
import pytest

from openptrack_py.config import (
    NetworkConfig,
    Pose,
    PoseError,
    SensorConfig,
    SimConfig,
    load_network,
)
from openptrack_py.config.sim import ProfileName
from openptrack_py.errors import ConfigError
from openptrack_py.messages.codec import encode_detection_batch, encode_ground_truth
from openptrack_py.sensor_types import SENSOR_TYPES
from openptrack_py.sim import SensorFrame, SensorModel, SensorSpec, Simulator, build_scenario
from openptrack_py.sim.false_positives import DECOY_KINDS
from openptrack_py.sim.live import scenario_from_network
from openptrack_py.sim.profiles import (
    IDEAL,
    PROFILE_NAMES,
    PROFILES,
    REALISTIC,
    NoiseProfile,
    resolve_profile,
)
from openptrack_py.sim.visibility import SensorView, visible_summary
from openptrack_py.sim.world import Obstacle, Room
from tests.conftest import ROOT, people_snapshot

DEMO = ROOT / "config" / "demo.yaml"
FRONT = Pose(x=0.0, y=5.0, z=2.2, yaw_deg=0.0, pitch_deg=12.0)


def _model(
    profile: NoiseProfile | str = "ideal",
    room: Room | None = None,
    seed: int = 0,
    kind: str = "kinect2",
    **spec_options: object,
) -> SensorModel:
    spec = SensorSpec(
        id="s",
        type=SENSOR_TYPES[kind],
        pose=FRONT,
        rate_hz=30.0,
        **spec_options,  # type: ignore[arg-type]
    )
    return SensorModel(
        spec, room or Room(20.0, 10.0), np.random.default_rng(seed), profile=profile
    )


def _stream(scenario) -> list[tuple]:
    out = []
    for ev in Simulator(scenario).events():
        if isinstance(ev, SensorFrame):
            out.append((ev.time, encode_detection_batch(ev.batch), ev.person_ids))
        else:
            out.append((ev.time, encode_ground_truth(ev.frame)))
    return out


# Four people 2.5-4.5 m in front of the sensor, at bearings far enough apart that none
# hides or merges with another.
SPREAD = [
    (d * math.cos(b), 5.0 + d * math.sin(b))
    for d, b in zip((2.5, 4.5, 3.0, 4.0), np.radians((-20.0, -7.0, 7.0, 20.0)), strict=True)
]


def _errors(profile: NoiseProfile | str, seeds: int = 5, frames: int = 900) -> np.ndarray:
    """Per seed, person and frame: the floor error vector (NaN when missed)."""
    people = [(x, y, 1.75, 0.2, 0.0, 0.0) for x, y in SPREAD]
    out = np.full((seeds, len(people), frames, 2), np.nan)
    for seed in range(seeds):
        model = _model(profile, seed=seed, clutter_per_frame=0.0)
        for k in range(frames):
            snap = people_snapshot(people, t=k / 30.0)
            obs = model.observe(snap)
            for det, pid in zip(obs.detections, obs.person_ids, strict=True):
                if pid:
                    out[seed, pid - 1, k] = (
                        det.x - snap.pos[pid - 1, 0],
                        det.y - snap.pos[pid - 1, 1],
                    )
    return out


@pytest.fixture(scope="module")
def realistic_errors() -> np.ndarray:
    return _errors("realistic")


# ================================================================ 1. ideal is today


@pytest.mark.parametrize("name", ["crowd", "occlusions"])
def test_ideal_profile_is_the_default_bit_for_bit(name: str) -> None:
    default = build_scenario(name, seed=3, duration_s=3.0)
    ideal = build_scenario(name, seed=3, duration_s=3.0, profile="ideal")
    assert default.profile is IDEAL and ideal.profile is IDEAL
    assert default.sensors == ideal.sensors and ideal.decoys == ()
    assert _stream(default) == _stream(ideal)


def test_a_profile_with_every_feature_off_draws_nothing_extra() -> None:
    """Switched-off mechanisms draw no random numbers: the streams stay the same."""
    off = dataclasses.replace(IDEAL, name="ideal-copy")
    assert _stream(build_scenario("crowd", seed=2, duration_s=2.0, profile=off)) == _stream(
        build_scenario("crowd", seed=2, duration_s=2.0)
    )


def test_false_positives_do_not_move_the_true_detections() -> None:
    """Each mechanism has its own generator: adding false positives leaves people alone."""
    snap = people_snapshot([(x, y, 1.75, 0.2, 0.0, 0.0) for x, y in SPREAD])
    quiet = dataclasses.replace(REALISTIC, false_positives_per_frame=0.0)
    noisy = dataclasses.replace(REALISTIC, false_positives_per_frame=3.0)
    a, b = _model(quiet, seed=4), _model(noisy, seed=4)
    extra = 0
    for _ in range(60):
        oa, ob = a.observe(snap), b.observe(snap)
        real_a = [
            (d.x, d.y, pid) for d, pid in zip(oa.detections, oa.person_ids, strict=True) if pid
        ]
        real_b = [
            (d.x, d.y, pid) for d, pid in zip(ob.detections, ob.person_ids, strict=True) if pid
        ]
        assert real_a == real_b
        extra += ob.person_ids.count(0) - oa.person_ids.count(0)
    assert extra > 60


def test_profiles_never_change_the_peoples_paths() -> None:
    truth = {}
    for profile in PROFILE_NAMES:
        sim = Simulator(build_scenario("crowd", seed=1, duration_s=2.0, profile=profile))
        truth[profile] = [encode_ground_truth(e.frame) for e in sim.events(sensor_frames=False)]
    assert truth["ideal"] == truth["realistic"] == truth["harsh"]


# ============================================================ 2. centroid error


def test_realistic_error_matches_the_childcare_papers_figures(realistic_errors) -> None:
    """Childcare paper: single-frame detection error about 10 cm, standard deviation 8 cm."""
    e = realistic_errors.reshape(-1, 2)
    r = np.hypot(*e[~np.isnan(e[:, 0])].T)
    assert 0.085 <= r.mean() <= 0.115
    assert 0.06 <= r.std() <= 0.10
    assert r.std() / r.mean() > 0.6  # heavier-tailed than a 2-D Gaussian's 0.52


def test_ideal_error_is_small_and_gaussian() -> None:
    e = _errors("ideal", seeds=2, frames=300).reshape(-1, 2)
    r = np.hypot(*e[~np.isnan(e[:, 0])].T)
    assert r.mean() < 0.06
    assert r.std() / r.mean() < 0.6


def _lag_correlation(errors: np.ndarray, lag: int) -> float:
    a = errors[..., :-lag, 0].ravel()
    b = errors[..., lag:, 0].ravel()
    ok = ~np.isnan(a) & ~np.isnan(b)
    return float(np.corrcoef(a[ok], b[ok])[0, 1])


def test_one_sensors_error_on_a_person_persists_over_frames(realistic_errors) -> None:
    """Over 0.2 s one sensor's error on one person is clearly correlated (ideal: not)."""
    assert _lag_correlation(realistic_errors, 6) > 0.15
    # and it fades over a few time constants
    assert _lag_correlation(realistic_errors, 150) < 0.05
    ideal = _errors("ideal", seeds=2, frames=300)
    assert abs(_lag_correlation(ideal, 6)) < 0.05


def test_error_grows_with_distance_fastest_for_kinect1() -> None:
    def mean_error(kind: str, x: float) -> float:
        model = _model("realistic", kind=kind, clutter_per_frame=0.0, miss_probability=0.0)
        errors = []
        for k in range(1500):
            snap = people_snapshot([(x, 5.0, 1.75, 0.2, 0.0, 0.0)], t=k / 30.0)
            obs = model.observe(snap)
            errors += [
                math.hypot(d.x - x, d.y - 5.0)
                for d, p in zip(obs.detections, obs.person_ids, strict=True)
                if p
            ]
        return float(np.mean(errors))

    k2_near, k2_far = mean_error("kinect2", 3.0), mean_error("kinect2", 7.0)
    k1_near, k1_far = mean_error("kinect1", 3.0), mean_error("kinect1", 7.0)
    assert k2_far > k2_near * 0.95 and k2_far < k2_near * 1.6
    assert k1_far > 1.8 * k1_near
    assert k1_far > 1.5 * k2_far


def test_noise_scale_multiplies_the_centroid_error() -> None:
    e1 = _errors("realistic", seeds=2, frames=600).reshape(-1, 2)
    e2 = _errors(REALISTIC.scaled(noise=2.0), seeds=2, frames=600).reshape(-1, 2)
    r1 = np.hypot(*e1[~np.isnan(e1[:, 0])].T).mean()
    r2 = np.hypot(*e2[~np.isnan(e2[:, 0])].T).mean()
    assert r2 / r1 == pytest.approx(2.0, rel=0.1)


# ============================================================ 3. partial occlusion


def test_visibility_mask_agrees_with_visibility() -> None:
    room = Room(20.0, 10.0, obstacles=(Obstacle("cab", 3.0, 5.03, 3.3, 5.8, 2.0),))
    view = SensorView(_model().spec, room)
    snap = people_snapshot([(4.0, 5.0, 1.75, 0.22, 0, 0), (6.0, 5.1, 1.7, 0.2, 0, 0)])
    mask = view.visibility_mask(snap)
    assert mask.shape == (2, 7)
    head, fraction = view.visibility(snap)
    h2, f2 = visible_summary(mask)
    assert head.tolist() == h2.tolist() and fraction.tolist() == f2.tolist()


@pytest.mark.parametrize(("profile", "shift"), [("realistic", -0.0825), ("ideal", 0.0)])
def test_half_hidden_person_is_detected_towards_the_visible_side(
    profile: str, shift: float
) -> None:
    # A cabinet hides the person's left half (+y, as the sensor looks along +x): the
    # visible points' centroid is 0.375 body radii to the right.
    room = Room(20.0, 10.0, obstacles=(Obstacle("cab", 3.0, 5.03, 3.3, 5.8, 2.0),))
    model = _model(profile, room=room, clutter_per_frame=0.0)
    mask = model.visibility_mask(people_snapshot([(4.0, 5.0, 1.75, 0.22, 0, 0)]))
    # head, right shoulder, chest, right hip, knees seen; left shoulder and hip hidden
    assert mask[0].tolist() == [True, True, False, True, True, False, True]
    dy = []
    for k in range(900):
        obs = model.observe(people_snapshot([(4.0, 5.0, 1.75, 0.22, 0, 0)], t=k / 30))
        dy += [d.y - 5.0 for d, p in zip(obs.detections, obs.person_ids, strict=True) if p]
    assert len(dy) > 500
    assert np.median(dy) == pytest.approx(shift, abs=0.03)


# =================================================================== 4. decoys


@pytest.fixture(scope="module")
def crowd_realistic():
    scenario = build_scenario("crowd", seed=0, duration_s=12.0, profile="realistic")
    return scenario, list(Simulator(scenario, ground_truth_rate_hz=None).events())


def test_decoys_are_placed_from_the_seed_on_free_seen_floor(crowd_realistic) -> None:
    scenario, _ = crowd_realistic
    assert len(scenario.decoys) == math.ceil(REALISTIC.decoys_per_sensor * 3)
    views = [SensorView(s, scenario.room) for s in scenario.sensors]
    for decoy in scenario.decoys:
        assert decoy.kind in DECOY_KINDS
        assert scenario.room.free(np.array([decoy.x, decoy.y]), 0.3)[0]
        assert any(v.sees(decoy.position_at(0.0)[None])[0] for v in views)
        if decoy.kind == "fan":
            assert 0.1 <= decoy.sway_m <= 0.2
    again = build_scenario("crowd", seed=0, duration_s=12.0, profile="realistic")
    other = build_scenario("crowd", seed=1, duration_s=12.0, profile="realistic")
    assert again.decoys == scenario.decoys != other.decoys


def test_decoys_recur_at_one_place_for_every_sensor_that_sees_them(crowd_realistic) -> None:
    scenario, events = crowd_realistic
    frames: dict[str, int] = defaultdict(int)
    sightings: dict[tuple[int, str], list[float]] = defaultdict(list)
    start = events[0].capture_time - scenario.sensors[0].phase_s if events else 0.0
    for ev in events:
        sensor = ev.batch.sensor_id
        frames[sensor] += 1
        t = ev.capture_time - start
        for det, pid in zip(ev.batch.detections, ev.person_ids, strict=True):
            if pid:
                continue
            for i, decoy in enumerate(scenario.decoys):
                gap = math.dist((det.x, det.y), decoy.position_at(t)[:2])
                if gap < 0.4:
                    sightings[(i, sensor)].append(det.confidence)
    for i, decoy in enumerate(scenario.decoys):
        seen_by = [
            s for (j, s), confs in sightings.items() if j == i and len(confs) > 0.05 * frames[s]
        ]
        assert seen_by, f"decoy {decoy} never recurs"
        for s in seen_by:
            # (a transient false positive or a split may pass close by, too)
            confs = np.array(sightings[(i, s)])
            assert np.mean((confs >= 0.5) & (confs <= 0.8)) > 0.9
    # at least one decoy is reported by two sensors at the same place
    assert any(
        sum(1 for (j, s), c in sightings.items() if j == i and len(c) > 0.05 * frames[s]) >= 2
        for i in range(len(scenario.decoys))
    )


# ====================================================== 5. sensor faults per sensor


def test_realistic_network_has_per_sensor_calibration_and_clock_offsets(crowd_realistic) -> None:
    scenario, _ = crowd_realistic
    offsets = [math.hypot(s.pose_error.dx, s.pose_error.dy) for s in scenario.sensors]
    yaws = [abs(s.pose_error.dyaw_deg) for s in scenario.sensors]
    clocks = [s.clock_offset_s for s in scenario.sensors]
    assert all(0.05 <= o <= 0.12 for o in offsets) and len(set(offsets)) == 3
    assert all(1.0 <= y <= 2.0 for y in yaws)
    assert all(abs(c) <= 0.02 for c in clocks) and len(set(clocks)) == 3
    for s in scenario.sensors:
        assert s.latency_jitter_s >= 0.015 and s.frame_drop_probability >= 0.01
        assert s.miss_probability == REALISTIC.miss_probability["kinect2"]
    harsh = build_scenario("crowd", seed=0, duration_s=1.0, profile="harsh")
    assert all(0.10 <= math.hypot(s.pose_error.dx, s.pose_error.dy) <= 0.20 for s in harsh.sensors)
    assert all(abs(s.clock_offset_s) <= 0.1 for s in harsh.sensors)


def test_sensors_of_one_network_disagree_on_where_a_person_is() -> None:
    """Calibration offsets put one sensor's detections of a person off another's."""

    def disagreement(profile: str) -> float:
        scenario = build_scenario("crowd", seed=0, duration_s=10.0, profile=profile)
        sim = Simulator(scenario, ground_truth_rate_hz=None)
        sums: dict[tuple[int, int], list[np.ndarray]] = defaultdict(list)
        for k in range(300):
            snap = sim.world.state_at(k / 30.0)
            pos = {int(p): snap.pos[i] for i, p in enumerate(snap.ids)}
            for m, model in enumerate(sim.models):
                obs = model.observe(snap)
                for det, pid in zip(obs.detections, obs.person_ids, strict=True):
                    if pid:
                        sums[(pid, m)].append(np.array([det.x, det.y]) - pos[pid])
        bias = {key: np.mean(v, axis=0) for key, v in sums.items() if len(v) > 100}
        gaps = [
            np.linalg.norm(bias[(p, a)] - bias[(p, b)])
            for (p, a) in bias
            for (q, b) in bias
            if p == q and a < b
        ]
        return float(np.median(gaps))

    assert disagreement("realistic") > 0.06
    assert disagreement("ideal") < 0.03


def test_single_sensor_has_no_calibration_error_and_configured_faults_are_kept() -> None:
    single = build_scenario("distance", seed=0, duration_s=1.0, profile="realistic")
    assert single.sensors[0].pose_error == PoseError()
    assert single.sensors[0].clock_offset_s != 0.0
    own = PoseError(dx=0.3, dy=0.0, dyaw_deg=0.0)
    sensors = [
        SensorConfig(id="a", pose=Pose(x=0.2, y=0.2, yaw_deg=45.0), pose_error=own,
                     clock_offset_s=0.5, miss_probability=0.3),
        SensorConfig(id="b", pose=Pose(x=9.8, y=0.2, yaw_deg=135.0)),
    ]  # fmt: skip
    scenario = build_scenario("crowd", duration_s=1.0, sensors=sensors, profile="realistic")
    a, b = scenario.sensors
    assert a.pose_error == own and a.clock_offset_s == 0.5 and a.miss_probability == 0.3
    assert b.pose_error != PoseError() and b.miss_probability == 0.05


# ================================================= 6. false positives, splits, merges


def test_transient_false_positives_are_confident_and_last_a_while() -> None:
    profile = REALISTIC.with_false_positives(2.0, max_confidence=0.8)
    model = _model(profile, clutter_per_frame=0.0)
    empty = people_snapshot([])
    counts, confs, runs = [], [], []
    previous: list[tuple[tuple[float, float], int]] = []  # (position, frames so far)
    for k in range(3000):
        obs = model.observe(dataclasses.replace(empty, t=k / 30.0))
        counts.append(len(obs.detections))
        confs += [d.confidence for d in obs.detections]
        current, continued = [], set()
        for det in obs.detections:
            p = (det.x, det.y)
            before = [j for j, (q, _) in enumerate(previous) if math.dist(p, q) < 0.05]
            length = previous[before[0]][1] + 1 if before else 1
            continued.update(before[:1])
            current.append((p, length))
        runs += [n for j, (_, n) in enumerate(previous) if j not in continued]
        previous = current
    assert np.mean(counts) == pytest.approx(2.0, rel=0.15)
    assert max(confs) <= 0.8 and np.mean(np.array(confs) >= 0.7) > 0.1
    # they last several frames (mean lifetime 0.4 s = 12 frames), drifting slowly
    assert np.mean(runs) > 5


def test_realistic_transient_rate_without_the_extras() -> None:
    model = _model("realistic", clutter_per_frame=0.0)
    empty = people_snapshot([])
    counts = [
        len(model.observe(dataclasses.replace(empty, t=k / 30)).detections) for k in range(30000)
    ]
    assert np.mean(counts) == pytest.approx(REALISTIC.false_positives_per_frame, rel=0.35)


def test_splits_persist_beside_a_person() -> None:
    profile = dataclasses.replace(REALISTIC, split_probability=0.05, split_duration_s=0.5,
                                  false_positives_per_frame=0.0)  # fmt: skip
    snap = people_snapshot([(4.0, 5.0, 1.75, 0.2, 0, 0)])

    def split_runs(model: SensorModel) -> list[int]:
        runs, current = [], 0
        for k in range(1500):
            obs = model.observe(dataclasses.replace(snap, t=k / 30.0))
            fakes = [d for d, p in zip(obs.detections, obs.person_ids, strict=True) if not p]
            person = obs.detections[obs.person_ids.index(1)]
            if fakes:  # beside the person's detection
                assert all(
                    0.2 <= math.dist((d.x, d.y), (person.x, person.y)) <= 0.7 for d in fakes
                )
                current += 1
            elif current:
                runs.append(current)
                current = 0
        return runs

    persistent = split_runs(_model(profile, clutter_per_frame=0.0, miss_probability=0.0))
    assert len(persistent) > 10 and np.mean(persistent) > 5
    one_frame = split_runs(_model("ideal", clutter_per_frame=0.0, miss_probability=0.0))
    assert all(r == 1 for r in one_frame)


@pytest.mark.parametrize(("profile", "count"), [("ideal", 2), ("realistic", 1)])
def test_realistic_merges_people_walking_shoulder_to_shoulder(profile: str, count: int) -> None:
    model = _model(profile, clutter_per_frame=0.0, miss_probability=0.0)
    assert model.merge_distance_m == PROFILES[profile].merge_distance_m
    snap = people_snapshot([(4.0, 4.8, 1.7, 0.1, 0, 0), (4.0, 5.2, 1.8, 0.1, 0, 0)])
    for k in range(20):
        obs = model.observe(dataclasses.replace(snap, t=k / 30.0))
        assert sum(1 for p in obs.person_ids if p) == count


def test_realistic_misses_more_than_ideal() -> None:
    snap = people_snapshot([(4.0, 5.0, 1.75, 0.2, 0, 0)])
    rates = {}
    for profile in ("ideal", "realistic"):
        scenario = build_scenario(
            "distance", duration_s=1.0, profile=profile,
            sensors=[SensorConfig(id="s", pose=FRONT, clutter_per_frame=0.0)],
        )  # fmt: skip
        model = Simulator(scenario).models[0]
        found = [
            1 in model.observe(dataclasses.replace(snap, t=k / 30)).person_ids for k in range(3000)
        ]
        rates[profile] = 1 - np.mean(found)
    assert rates["ideal"] == pytest.approx(0.02, abs=0.01)
    assert rates["realistic"] == pytest.approx(0.05, abs=0.015)


# ================================================= 7. names, variants, config, seeds


def test_profile_names_match_the_config_literal() -> None:
    assert PROFILE_NAMES == typing.get_args(ProfileName) == ("ideal", "realistic", "harsh")
    assert SimConfig().profile == "realistic"


def test_unknown_profile_names_the_allowed_ones() -> None:
    with pytest.raises(
        ConfigError, match=r"profile: unknown 'noisy' \(allowed: ideal, realistic, harsh\)"
    ):
        build_scenario("crowd", profile="noisy")
    assert resolve_profile(REALISTIC) is REALISTIC


def test_sim_profile_in_a_network_file_is_validated() -> None:
    with pytest.raises(ConfigError) as info:
        load_network(DEMO, ["sim.profile=noisy"])
    text = str(info.value)
    assert "sim.profile" in text
    assert all(name in text for name in ("'ideal'", "'realistic'", "'harsh'"))
    harsh = load_network(DEMO, ["sim.profile=harsh"]).sim
    assert harsh is not None and harsh.profile == "harsh"


def test_scenario_from_network_uses_the_networks_profile() -> None:
    sensors = [
        SensorConfig(id="a", pose=FRONT),
        SensorConfig(id="b", pose=Pose(x=9.0, y=5.0, yaw_deg=180.0)),
    ]
    for profile in PROFILE_NAMES:
        cfg = NetworkConfig(sensors=sensors, sim=SimConfig(scenario="crowd", profile=profile))
        assert scenario_from_network(cfg).profile is PROFILES[profile]


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"noise_scale": -1.0}, r"noise_scale must be in \[0, 10\] \(received -1.0\)"),
        ({"outlier_probability": 1.5}, r"outlier_probability must be in \[0, 1\]"),
        ({"calibration_offset_m": (0.2, 0.1)}, r"calibration_offset_m\[1\] must be in \[0.2, 2\]"),
        (
            {"miss_probability": {"kinect9": 0.1}},
            r"miss_probability: unknown sensor type kinect9 \(allowed: kinect1",
        ),
        ({"merge_distance_m": float("nan")}, r"merge_distance_m must be in"),
    ],
)
def test_profile_values_are_validated(changes: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=rf"profile realistic: {message}"):
        dataclasses.replace(REALISTIC, **changes)


def test_sweep_variants() -> None:
    loud = REALISTIC.scaled(noise=2.0, misses=2.0, false_positives=0.5)
    assert loud.noise_scale == 2.0 and loud.name != REALISTIC.name
    assert loud.miss_probability["kinect2"] == pytest.approx(0.10)
    assert loud.false_positives_per_frame == pytest.approx(REALISTIC.false_positives_per_frame / 2)
    off = REALISTIC.with_calibration_error(0.3, yaw_deg=0.0)
    scenario = build_scenario("crowd", duration_s=1.0, profile=off)
    for s in scenario.sensors:
        assert math.hypot(s.pose_error.dx, s.pose_error.dy) == pytest.approx(0.3)
        assert s.pose_error.dyaw_deg == 0.0
    quiet = REALISTIC.with_false_positives(0.0, decoys_per_sensor=0.0)
    assert build_scenario("crowd", duration_s=1.0, profile=quiet).decoys == ()
    with pytest.raises(ConfigError, match="false_positive_max_confidence"):
        REALISTIC.with_false_positives(1.0, max_confidence=1.5)


@pytest.mark.parametrize("profile", ["realistic", "harsh"])
def test_same_seed_same_batches_other_seed_other_batches(profile: str) -> None:
    a = _stream(build_scenario("crowd", seed=5, duration_s=2.0, profile=profile))
    b = _stream(build_scenario("crowd", seed=5, duration_s=2.0, profile=profile))
    c = _stream(build_scenario("crowd", seed=6, duration_s=2.0, profile=profile))
    assert a == b
    assert a != c
