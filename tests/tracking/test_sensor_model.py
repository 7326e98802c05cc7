"""What the tracker learns about each sensor: noise scale, bias, coverage."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from openptrack_py.config import TrackerConfig
from openptrack_py.messages.detection import Detection, DetectionBatch
from openptrack_py.tracking import OnlineSensorModel, build_tracker
from openptrack_py.tracking.bookkeeping import learnable_updates
from openptrack_py.tracking.sensor_model import SensorUpdates, gated_noise_scale
from openptrack_py.tracking.state import DetectionArrays, TrackTable
from tests.tracking.helpers import FRAME, T0

GATE = float(chi2.ppf(0.95, 2))


@pytest.mark.parametrize("scale", [0.5, 1.0, 4.0, 9.0])
@pytest.mark.parametrize("track_var", [0.0, 0.01], ids=["sharp-track", "uncertain-track"])
def test_the_noise_scale_of_gated_innovations_is_recovered(scale: float, track_var: float) -> None:
    rng = np.random.default_rng(int(scale * 10))
    model_var = 0.01
    sigma2 = track_var + scale * model_var
    nu = rng.normal(0.0, np.sqrt(sigma2), (20_000, 2))
    q = (nu**2).sum(axis=1)
    # gated with the scale the samples will be found to have: the fixed point
    cut = GATE * sigma2
    q = q[q <= cut][:2000]
    rows = np.column_stack([q, np.full(len(q), track_var), np.full(len(q), model_var),
                            np.full(len(q), cut)])  # fmt: skip
    assert gated_noise_scale(rows, (0.25, 25.0)) == pytest.approx(scale, rel=0.15)


def test_a_too_narrow_gate_is_seen_and_the_scale_grows() -> None:
    rng = np.random.default_rng(1)
    nu = rng.normal(0.0, 0.3, (5000, 2))  # true variance 9 times the model's 0.01
    q = (nu**2).sum(axis=1)
    cut = GATE * 0.01
    q = q[q <= cut][:500]
    rows = np.column_stack([q, np.zeros(len(q)), np.full(len(q), 0.01), np.full(len(q), cut)])
    assert gated_noise_scale(rows, (0.25, 25.0)) > 3.0


def test_the_noise_scale_is_bounded() -> None:
    big = np.tile([5.9, 0.0, 1.0, GATE], (100, 1))
    small = np.tile([1e-6, 0.0, 1.0, GATE], (100, 1))
    assert gated_noise_scale(big, (0.5, 2.0)) == pytest.approx(2.0, rel=1e-3)
    assert gated_noise_scale(small, (0.5, 2.0)) == pytest.approx(0.5, rel=1e-3)


def _walk(tracker, noise, offset, seconds, start_s=0.0):
    """One person walking a circle, seen by every sensor of ``noise`` at 30 Hz."""
    rng = np.random.default_rng(7 + int(start_s))
    for k in range(int(start_s / FRAME), int((start_s + seconds) / FRAME)):
        for i, (sensor, sigma) in enumerate(noise.items()):
            t = k * FRAME + 0.01 * i
            xy = np.array([3 + 2 * np.cos(0.3 * t), 3 + 2 * np.sin(0.3 * t)])
            xy = xy + offset.get(sensor, 0.0) + rng.normal(0, sigma, 2)
            d = Detection(x=xy[0], y=xy[1], z=1.0, height=1.7, confidence=0.9, distance=3.0)
            tracker.step(DetectionBatch(sensor, k, T0 + t, "world", (d,)))


def test_a_noisier_sensor_gets_a_larger_noise_scale() -> None:
    tracker = build_tracker(TrackerConfig())
    # the configured model says 0.08 + 0.002 * 3**2 = 0.098 m at 3 m
    _walk(tracker, {"quiet": 0.05, "loud": 0.25}, {}, 15.0)
    started = tracker.counters["tracks_started"]
    _walk(tracker, {"quiet": 0.05, "loud": 0.25}, {}, 45.0, start_s=15.0)
    at_3m = np.array([3.0])
    quiet = tracker.sensors.noise_scale("quiet", at_3m)[0]
    loud = tracker.sensors.noise_scale("loud", at_3m)[0]
    # true variances: (0.05 / 0.098)^2 = 0.26 and (0.25 / 0.098)^2 = 6.5 times the model
    assert 0.15 < quiet < 0.5
    assert 3.0 < loud < 15.0
    # once learned, the loud sensor's detections no longer start tracks
    assert tracker.counters["tracks_started"] == started


def test_a_sensor_offset_against_the_others_is_learned_and_removed() -> None:
    tracker = build_tracker(TrackerConfig())
    shift = np.array([0.15, -0.10])
    _walk(tracker, {"a": 0.05, "b": 0.05, "c": 0.05}, {"c": shift}, 60.0)
    biases = {s: tracker.sensors.bias(s) for s in "abc"}
    # relative offsets are what is observable: c against the mean of a and b
    relative = biases["c"] - (biases["a"] + biases["b"]) / 2
    np.testing.assert_allclose(relative, shift, atol=0.03)
    # the gauge: the sample-weighted mean of the biases stays at zero
    assert np.hypot(*sum(biases.values())) < 0.05


def test_sensors_headings_off_along_a_long_hall_leave_the_world_where_their_data_are() -> None:
    """Eight sensors along a 28 m hall, each seeing the floor 2-6 m in front of it, each
    with its heading off about its own position (the left half +2 degrees, the right
    half -2: their mean is zero). Learned against the true places, every
    correction must stay the true one where the sensor's data are. Holding the mean
    correction at the identity at the hall's centre instead carried each sensor's
    rotation 2-14 m from its data and left the sensors 0.06-0.5 m off."""
    from openptrack_py.tracking.alignment import rotation

    model = OnlineSensorModel()
    rng = np.random.default_rng(7)
    xs = np.arange(8) * 4.0
    yaws = np.radians(np.where(xs < 14.0, 2.0, -2.0))
    views = [np.column_stack([x + rng.uniform(-2, 2, 40), rng.uniform(2, 6, 40)]) for x in xs]
    ones = np.ones(40)

    def raw(k: int, places: np.ndarray) -> np.ndarray:  # the sensor at (x, 0) turned by yaw
        at = np.array([xs[k], 0.0])
        return (places - at) @ rotation(yaws[k]).T + at

    for _ in range(20):  # 800 pairs per sensor, fitted every 30
        for k, places in enumerate(views):
            theta, shift = model.alignment(f"s{k}")
            corrected = raw(k, places) @ rotation(theta).T + shift
            model.learn(SensorUpdates(f"s{k}", corrected, places, 4 * ones, 0 * ones,
                                      0.01 * ones, GATE, ones > 0))  # fmt: skip
    for k, places in enumerate(views):
        theta, shift = model.alignment(f"s{k}")
        mapped = raw(k, places) @ rotation(theta).T + shift
        assert np.abs(mapped - places).max() < 0.03  # the old gauge: 0.06-0.5 m


def test_one_sensor_alone_learns_no_bias() -> None:
    tracker = build_tracker(TrackerConfig())
    _walk(tracker, {"only": 0.05}, {"only": np.array([0.3, 0.0])}, 20.0)
    np.testing.assert_allclose(tracker.sensors.bias("only"), 0.0)


def test_bias_and_scale_are_bounded() -> None:
    model = OnlineSensorModel(max_bias_m=0.2, scale_bounds=(0.5, 4.0), min_samples=10)
    ones = np.ones(5)
    spread = np.column_stack([np.linspace(0, 4, 5), np.linspace(0, 4, 5)])

    def updates(sensor: str, offset: float) -> SensorUpdates:
        return SensorUpdates(sensor, spread + offset, spread, 3 * ones, 0 * ones,
                             0.01 * ones, GATE, ones > 0)  # fmt: skip

    for _ in range(200):
        model.learn(updates("s", 1.0))
        model.learn(updates("t", 0.0))
    assert np.hypot(*model.bias("s")) <= 0.2 + 1e-9
    assert model.noise_scale("s", np.array([3.0]))[0] <= 4.0


def test_an_unlearned_calibration_widens_only_pairs_of_different_sensors() -> None:
    """Against a track another sensor fed, a detection gets both sensors' calibration
    uncertainty (shift and yaw at its distance); against its own sensor's, nothing; it
    shrinks as the sensor's alignment rests on more pairs, and is 0 when calibrations
    are trusted."""
    from openptrack_py.tracking.sensor_model import ALIGNMENT_PAIR_VAR_M2
    from openptrack_py.tracking.static_sensors import StaticSensorModel

    model = OnlineSensorModel(calibration_sigma=(0.12, 2.0))
    distance = np.array([1.0, 5.0])
    last = np.array([0, 1, 1, -1])  # tracks last fed by "a", "b", "b", nobody known
    var = model.cross_sensor_var("a", distance, last, ["a", "b"])
    prior = 0.12**2 + (np.radians(2.0) * distance) ** 2
    np.testing.assert_allclose(var[0], 0.0)  # its own track: its error is common
    np.testing.assert_allclose(var[1], 2 * prior)
    np.testing.assert_allclose(var[3], 2 * prior)
    spread = np.column_stack([np.linspace(0, 4, 30), np.linspace(0, 4, 30)])
    ones = np.ones(30)
    for _ in range(4):  # 120 pairs, fitted every 30
        model.learn(SensorUpdates("b", spread, spread, 3 * ones, 0 * ones, 0.01 * ones, GATE,
                                  ones > 0))  # fmt: skip
    pairs = model._sensors["b"].align.fitted_weight
    assert 100 < pairs <= 120
    settled = model.cross_sensor_var("a", distance, last, ["a", "b"])
    posterior = 1 / (1 / prior + pairs / ALIGNMENT_PAIR_VAR_M2)  # b's; a learned nothing
    np.testing.assert_allclose(settled[1], prior + posterior)
    assert (posterior < 0.2 * prior).all()
    for trusted in (OnlineSensorModel(), OnlineSensorModel(calibration_sigma=(0.12, 2.0),
                                                           estimate_bias=False),
                    StaticSensorModel()):  # fmt: skip
        assert trusted.cross_sensor_var("a", distance, last, ["a", "b"]) is None


def test_coverage_is_where_a_sensor_reported_something() -> None:
    model = OnlineSensorModel()
    tracker = build_tracker(TrackerConfig())
    tracker.sensors = model
    d = Detection(x=1.2, y=3.7, z=1.0, height=1.7, confidence=0.9, distance=3.0)
    probe = np.array([[1.0, 3.6], [4.0, 4.0]])
    for k in range(5):
        assert model.covers("s", probe).tolist() == [False, False]  # not yet: a few first
        tracker.step(DetectionBatch("s", k, T0 + k * FRAME, "world", (d,)))
    assert model.covers("s", probe).tolist() == [True, False]
    assert model.covers("other", probe[:1]).tolist() == [False]
    # a batch applied again (a replay) is not counted twice
    again = OnlineSensorModel()
    from openptrack_py.tracking.state import DetectionArrays

    batch = DetectionArrays.from_batch(DetectionBatch("s", 7, T0, "world", (d,)), 0.0)
    for _ in range(10):
        again.correct(batch)
    assert again.covers("s", probe[:1]).tolist() == [False]


def test_learned_state_survives_a_late_batch_replay() -> None:
    late = build_tracker(TrackerConfig())
    ontime = build_tracker(TrackerConfig())
    _walk(late, {"a": 0.05, "b": 0.15}, {"b": np.array([0.1, 0.0])}, 10.0)
    _walk(ontime, {"a": 0.05, "b": 0.15}, {"b": np.array([0.1, 0.0])}, 10.0)
    t = late.time
    d = Detection(x=3.0, y=3.0, z=1.0, height=1.7, confidence=0.9, distance=3.0)
    extra = DetectionBatch("b", 10_000, t - 0.5, "world", (d,))
    late.step(DetectionBatch("a", 10_001, t + FRAME, "world", ()))
    late.step(extra)  # arrives late: replayed
    ontime.step(extra)
    ontime.step(DetectionBatch("a", 10_001, t + FRAME, "world", ()))
    assert late.counters["late_applied"] == 1
    at = np.array([2.0, 5.0])
    np.testing.assert_array_equal(
        late.sensors.noise_scale("b", at), ontime.sensors.noise_scale("b", at)
    )
    np.testing.assert_array_equal(late.sensors.bias("b"), ontime.sensors.bias("b"))


@pytest.mark.parametrize(("rival_confirmed", "learned"), [(False, True), (True, False)])
def test_a_pair_is_learned_from_unless_another_confirmed_track_could_take_its_detection(
    rival_confirmed: bool, learned: bool
) -> None:
    # one detection in the gates of a settled confirmed track and of another track: a
    # tentative one (the noise's own doing, unproven) leaves the pair clear
    tb = TrackTable()
    tb.ids = np.array([1, 2])
    tb.x = np.array([[0.0, 0.0, 0.0, 0.0], [0.3, 0.0, 0.0, 0.0]])
    tb.confirmed = np.array([True, rival_confirmed])
    tb.first_seen = np.array([-5.0, -0.5])
    tb.multi_t = np.full(2, -np.inf)
    tb.last_sensor = np.zeros(2, dtype=np.int64)
    dets = DetectionArrays(
        index=np.array([0]), xy=np.array([[0.1, 0.0]]), z=np.ones(1), height=np.ones(1),
        confidence=np.ones(1), distance=np.full(1, 3.0), sensor_id="a",
    )  # fmt: skip
    gated = np.array([[True], [True]])
    updates = learnable_updates(
        tb, np.array([0]), np.array([0]), dets, np.zeros((1, 2)), np.eye(2)[None] * 0.01,
        np.eye(2)[None] * 0.0064, gated, 0.0, 0, GATE,
    )  # fmt: skip
    assert (updates is not None) is learned


def test_cell_lookup_agrees_with_isin() -> None:
    """The coverage's sorted lookup is ``np.isin``: cells below, between, above and
    equal to the covered ones, negative coordinates included."""
    from openptrack_py.tracking.coverage import _cell_codes
    from openptrack_py.tracking.lookup import find_sorted

    rng = np.random.default_rng(5)
    for n_cells in (1, 2, 40):
        cells = np.unique(_cell_codes(rng.uniform(-20, 20, size=(n_cells, 2))))
        probe = np.concatenate([_cell_codes(rng.uniform(-25, 25, size=(300, 2))), cells])
        assert find_sorted(cells, probe)[1].tolist() == np.isin(probe, cells).tolist()
        assert find_sorted(cells, probe)[1].any()
