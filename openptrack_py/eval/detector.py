"""Scores the people detector on rendered scenes against ground truth.

A scenario is played; at each sampled instant every sensor's view is rendered
(:mod:`openptrack_py.sim.render`), the detector runs on it, and its world-frame
detections are matched one-to-one (Hungarian, on floor distance, within
``match_radius_m``) to the people present.

A person **should be found** when at least half of their head and ``min_visible`` of
their body show in the image and their whole body lies within the detector's depth
limit. A detection
matched to a person who should be found is a true positive; one matched to a person
who is barely visible (hidden behind others, cut by the image border) is neither
rewarded nor punished; any other detection is a false positive. Recall is over the
people who should be found; the position error is the floor distance of true positives.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from openptrack_py.config import DetectorConfig, SensorConfig
from openptrack_py.detection.pipeline import RANGE_CUT_M, PeopleDetector
from openptrack_py.geometry import apply, world_from_optical
from openptrack_py.sensor_types import SENSOR_TYPES
from openptrack_py.sim.render import DepthRenderer
from openptrack_py.sim.scenarios import Scenario, build_scenario, scenario_world
from openptrack_py.sim.world import Snapshot


@dataclass
class DetectorScore:
    """Counts and errors of one evaluation.

    Parameters
    ----------
    frames : int
        Sensor frames evaluated.
    expected : int
        People who should have been found (summed over frames).
    tp, fp, fn : int
        True positives, false positives, misses.
    errors : list of float
        Floor distance of each true positive, metres.
    detect_s : list of float
        Detector time per frame, seconds.
    """

    frames: int = 0
    expected: int = 0
    tp: int = 0
    fp: int = 0
    fn: int = 0
    errors: list[float] = field(default_factory=list)
    detect_s: list[float] = field(default_factory=list)

    def as_dict(self) -> dict[str, float | int]:
        """Summary figures: recall, precision, mean and p95 error, rates."""
        errors = np.array(self.errors)
        times = np.array(self.detect_s)
        return {
            "recall": self.tp / self.expected if self.expected else 1.0,
            "precision": self.tp / (self.tp + self.fp) if self.tp + self.fp else 1.0,
            "mean_error_m": float(errors.mean()) if len(errors) else 0.0,
            "p95_error_m": float(np.percentile(errors, 95)) if len(errors) else 0.0,
            "frames": self.frames,
            "expected": self.expected,
            "tp": self.tp,
            "fp": self.fp,
            "fn": self.fn,
            "detector_ms_p50": float(np.median(times) * 1e3) if len(times) else 0.0,
        }


def match_frame(
    detections_xy: np.ndarray,
    people_xy: np.ndarray,
    should_find: np.ndarray,
    radius_m: float,
    score: DetectorScore,
) -> None:
    """Match one frame's detections to the people present and add to ``score``."""
    n_det, n_gt = len(detections_xy), len(people_xy)
    matched_det = np.zeros(n_det, dtype=bool)
    matched_gt = np.zeros(n_gt, dtype=bool)
    if n_det and n_gt:
        dist = np.linalg.norm(detections_xy[:, None, :] - people_xy[None, :, :], axis=2)
        cost = np.where(dist <= radius_m, dist, 1e6)
        rows, cols = linear_sum_assignment(cost)
        for r, c in zip(rows, cols, strict=True):
            if dist[r, c] > radius_m:
                continue
            matched_det[r] = matched_gt[c] = True
            if should_find[c]:
                score.tp += 1
                score.errors.append(float(dist[r, c]))
    score.fp += int((~matched_det).sum())
    score.fn += int((should_find & ~matched_gt).sum())
    score.expected += int(should_find.sum())
    score.frames += 1


MIXED_SCENARIOS = ("overhead", "classroom", "installation", "uniforms", "reentry")
"""Scenarios with children among the people: scored with the ``everyone`` preset."""


def detector_config_for(scenario: str) -> DetectorConfig:
    """Detector settings for a scenario: ``everyone`` with children present, else ``adult``."""
    return DetectorConfig(preset="everyone" if scenario in MIXED_SCENARIOS else "adult")


def scenario_for_sensor_type(
    name: str, seed: int, sensor_type: str, duration_s: float | None, **options: int
) -> Scenario:
    """A scenario with its own sensor placement, every sensor turned into ``sensor_type``.

    ``options`` are the scenario's own (e.g. ``children``), as for :func:`build_scenario`.
    """
    base = build_scenario(name, seed=seed, duration_s=duration_s, **options)
    sensors = [
        SensorConfig(id=s.id, type=sensor_type, pose=s.pose)  # type: ignore[arg-type]
        for s in base.sensors
    ]
    return build_scenario(name, seed=seed, duration_s=duration_s, sensors=sensors, **options)


def evaluate_detector(
    scenario: str = "crowd",
    *,
    seed: int = 0,
    sensor_type: str = "kinect2",
    duration_s: float = 30.0,
    sample_hz: float = 2.0,
    config: DetectorConfig | None = None,
    match_radius_m: float = 0.3,
    min_visible: float = 0.3,
) -> dict[str, object]:
    """Render a scenario, run the detector and score it.

    Parameters
    ----------
    scenario : str
        Scenario name.
    seed : int
        Random seed.
    sensor_type : str
        Type every scenario sensor becomes.
    duration_s : float
        Simulated time covered.
    sample_hz : float
        Instants evaluated per second (each renders every sensor).
    config : DetectorConfig, optional
        Detector settings; :func:`detector_config_for` the scenario if omitted.
    match_radius_m : float
        Largest floor distance of a match.
    min_visible : float
        Share of the body that must show for a person to count as findable.

    Returns
    -------
    dict
        ``recall, precision, mean_error_m, p95_error_m``, counts, and per-sensor figures.
    """
    if config is None:
        config = detector_config_for(scenario)
    sc = scenario_for_sensor_type(scenario, seed, sensor_type, duration_s)
    world = scenario_world(sc)
    cams = _cameras(sc, seed, sensor_type, config)
    total = DetectorScore()
    reach = min(SENSOR_TYPES[sensor_type].max_range_m, config.max_distance_for(sensor_type))
    steps = int(duration_s * sample_hz)
    for k in range(1, steps + 1):
        snap = world.state_at(k / sample_hz)
        for _spec, renderer, detector, score in cams:
            _score_view(renderer, detector, snap, k, reach, min_visible, match_radius_m,
                        (score, total))  # fmt: skip
    out: dict[str, object] = {
        "scenario": scenario,
        "seed": seed,
        "sensor_type": sensor_type,
        "preset": config.preset,
        "duration_s": duration_s,
        **total.as_dict(),
        "sensors": {spec.id: score.as_dict() for spec, _, _, score in cams},
    }
    return out


def _cameras(
    sc: Scenario, seed: int, sensor_type: str, config: DetectorConfig
) -> list[tuple[SensorConfig, DepthRenderer, PeopleDetector, DetectorScore]]:
    """A renderer, a detector and a score per sensor of the scenario."""
    cams = []
    for i, spec in enumerate(sc.sensors):
        renderer = DepthRenderer(spec, sc.room, np.random.default_rng([seed, 31, i]))
        detector = PeopleDetector(
            config,
            world_from_camera=world_from_optical(spec.pose),
            sensor_type=sensor_type,
            rng=np.random.default_rng([seed, 37, i]),
        )
        cams.append((spec, renderer, detector, DetectorScore()))
    return cams


def _score_view(
    renderer: DepthRenderer,
    detector: PeopleDetector,
    snap: Snapshot,
    k: int,
    reach: float,
    min_visible: float,
    match_radius_m: float,
    scores: tuple[DetectorScore, ...],
) -> None:
    """Render one sensor's view of ``snap``, detect, and match into every score."""
    shot = renderer.render(snap, stamp=snap.t, seq=k)
    t0 = time.perf_counter()
    result = detector.detect(shot.frame)
    elapsed = time.perf_counter() - t0
    # the whole body within the depth limit (the detector drops cut blobs)
    centre = np.column_stack([snap.pos, snap.height / 2])
    depth = apply(renderer.camera_from_world, centre)[:, 2]
    in_range = depth + snap.radius + RANGE_CUT_M <= reach
    with np.errstate(invalid="ignore", divide="ignore"):
        head_share = shot.head_visible / np.maximum(shot.head_pixels, 1)
        body_share = shot.visible_pixels / np.maximum(shot.body_pixels, 1)
    should = in_range & (head_share >= 0.5) & (body_share >= min_visible)
    should &= shot.head_pixels > 0
    det_xy = np.array([d.position[:2] for d in result.detections]).reshape(-1, 2)
    for target in scores:
        match_frame(det_xy, snap.pos, should, match_radius_m, target)
        target.detect_s.append(elapsed)
