"""Run a scenario faster than real time through a hypothesis source and score it.

The harness is the same whatever produces the hypotheses:

* Ground truth is sampled at every :class:`~openptrack_py.sim.simulator.TruthFrame`
  (30 Hz by default). Only people a sensor could see (``covered``: head inside some
  field of view and range, occlusion ignored) count as objects to track. How many of
  them a sensor detection had just reached (``seen``) is counted beside the metrics
  (:mod:`openptrack_py.eval.reach`): a ceiling no tracker's figures can pass by much.
* Hypotheses come from a :class:`HypothesisFeed`, asked for the tracks at each
  ground-truth time. :class:`TrackerFeed` runs a tracker on the sensor batches in
  arrival order and extrapolates its latest output to the ground-truth time with each
  track's velocity; if its latest output is older than ``stale_after_s`` the frame
  counts as missing (every object a miss). :class:`~openptrack_py.eval.oracle.TruthFeed`
  replays the ground truth itself, optionally with injected faults, to prove the harness.
* A hypothesis within ``max_distance_m`` of a person who is present but not covered
  (walking out of view, say) is neither rewarded nor punished: it is removed before
  scoring, like a "don't care" region.

:func:`evaluate` plays a simulated scenario; :func:`play` scores any time-ordered stream
of sensor and ground-truth frames the same way (:mod:`openptrack_py.eval.external`
builds one from files).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from scipy.optimize import linear_sum_assignment

from openptrack_py.eval.metrics import MotAccumulator, MotMetrics
from openptrack_py.eval.reach import SensorReach
from openptrack_py.messages.detection import DetectionBatch
from openptrack_py.messages.ground_truth import GroundTruthFrame
from openptrack_py.messages.track import TrackBatch
from openptrack_py.sim.scenarios import Scenario
from openptrack_py.sim.simulator import SensorFrame, Simulator, TruthFrame


@dataclass(frozen=True)
class Hypotheses:
    """Tracker output at one instant.

    Parameters
    ----------
    ids : ndarray of int
        Track ids.
    xy : ndarray
        ``(n, 2)`` positions, metres.
    """

    ids: np.ndarray
    xy: np.ndarray

    @classmethod
    def extrapolated(
        cls, ids: np.ndarray, rows: np.ndarray, since: float, t: float, stale_after_s: float
    ) -> Hypotheses | None:
        """Tracks output at true time ``since`` moved along their velocity to ``t``.

        ``rows`` is ``(n, 4)``: x, y, vx, vy. ``None`` when the output is older than
        ``stale_after_s`` (it counts as no output at all).
        """
        if t - since > stale_after_s:
            return None
        return cls(ids, rows[:, 0:2] + (t - since) * rows[:, 2:4])


class HypothesisFeed(Protocol):
    """Something that watches the simulation and says where it believes people are.

    A feed may also have ``on_sensors_ended()``, called when no sensor frame will
    follow (streams that know their end emit :class:`SensorsEnded`).
    """

    def on_sensor_frame(self, frame: SensorFrame) -> None:
        """A sensor batch reached the network at ``frame.time``."""

    def on_truth_frame(self, frame: TruthFrame) -> None:
        """Ground truth at ``frame.time`` (only oracles may look)."""

    def hypotheses_at(self, t: float) -> Hypotheses | None:
        """Tracks at true time ``t``; ``None`` when there is no usable output."""


class Pipeline(Protocol):
    """Takes batches as they arrive and steps a tracker (see ``tracking.pipeline``)."""

    def push(
        self, batch: DetectionBatch, arrival: float
    ) -> list[tuple[DetectionBatch, TrackBatch]]:
        """Take a batch at its arrival time; return the steps it allowed."""

    def poll(self, now: float) -> list[tuple[DetectionBatch, TrackBatch]]:
        """Steps whose wait ended by ``now``."""

    def flush(self) -> list[tuple[DetectionBatch, TrackBatch]]:
        """Steps with every batch still held."""


@dataclass
class TrackerFeed:
    """Feeds sensor batches to a tracking pipeline and reports its extrapolated output.

    Each output refers to the capture time of the batch that produced it; the feed maps
    it to true time through that batch's true capture time, so sensor clock offsets
    (and their correction) do not bias the scoring.

    Parameters
    ----------
    pipeline : Pipeline
        Reorder buffer plus tracker.
    stale_after_s : float
        Output older than this counts as no output at all.
    """

    pipeline: Pipeline
    stale_after_s: float = 1.0
    steps: int = 0
    step_seconds: float = 0.0
    _latest: TrackBatch | None = None
    _latest_true_time: float = -float("inf")
    _captures: dict[tuple[str, int], float] = field(default_factory=dict)

    def _take(self, results: list[tuple[DetectionBatch, TrackBatch]]) -> None:
        for batch, out in results:
            self.steps += 1
            true_time = self._captures.pop((batch.sensor_id, batch.seq), None)
            if true_time is not None and true_time >= self._latest_true_time:
                self._latest, self._latest_true_time = out, true_time

    def on_sensor_frame(self, frame: SensorFrame) -> None:
        """Push the batch at its arrival time (timing the steps it triggers)."""
        self._captures[(frame.batch.sensor_id, frame.batch.seq)] = frame.capture_time
        start = time.perf_counter()
        results = self.pipeline.push(frame.batch, frame.time)
        self.step_seconds += time.perf_counter() - start
        self._take(results)

    def on_truth_frame(self, frame: TruthFrame) -> None:
        """Use only the clock: release batches whose wait is over."""
        start = time.perf_counter()
        results = self.pipeline.poll(frame.time)
        self.step_seconds += time.perf_counter() - start
        self._take(results)

    def on_sensors_ended(self) -> None:
        """No batch will follow: apply those the reorder window still holds."""
        start = time.perf_counter()
        results = self.pipeline.flush()
        self.step_seconds += time.perf_counter() - start
        self._take(results)

    def hypotheses_at(self, t: float) -> Hypotheses | None:
        """Latest output extrapolated to ``t`` along each track's velocity."""
        if self._latest is None or t - self._latest_true_time > self.stale_after_s:
            return None
        dt = t - self._latest_true_time
        tracks = self._latest.tracks
        ids = np.array([tr.client_id for tr in tracks], dtype=np.int64)
        xy = np.array([(tr.x + tr.vx * dt, tr.y + tr.vy * dt) for tr in tracks]).reshape(-1, 2)
        return Hypotheses(ids, xy)


@dataclass(frozen=True, slots=True)
class SensorsEnded:
    """Event after the last sensor frame of a stream (the feed may flush what it holds).

    Parameters
    ----------
    time : float
        Time of the last sensor frame, seconds.
    """

    time: float


Event = SensorFrame | TruthFrame | SensorsEnded
"""What :func:`play` consumes, in time order."""


@dataclass(frozen=True)
class EvalResult:
    """Metrics of one run and how long it took.

    Parameters
    ----------
    metrics : MotMetrics
        CLEAR MOT and identity metrics.
    scenario : str
        Scenario name (the ground-truth file's name for files).
    seed : int or None
        Seed (``None`` for files: left out of :meth:`to_dict`).
    duration_s : float
        Simulated time (first to last ground-truth frame for files).
    sensors : int
        Number of sensors.
    batches : int
        Sensor batches produced.
    wall_s : float
        Wall-clock time of the run.
    tracker_ms_per_batch : float or None
        Mean tracker step time, when a tracker ran.
    reach : SensorReach or None
        What the sensors delivered (simulated runs, whose detections name their
        person): ``seen`` and ``idf1_seen`` in :meth:`to_dict`.
    """

    metrics: MotMetrics
    scenario: str
    seed: int | None
    duration_s: float
    sensors: int
    batches: int
    wall_s: float
    tracker_ms_per_batch: float | None = None
    reach: SensorReach | None = None

    def to_dict(self) -> dict[str, object]:
        """Flat JSON-ready mapping: run description first, then every metric."""
        out: dict[str, object] = {"scenario": self.scenario}
        if self.seed is not None:
            out["seed"] = self.seed
        out |= {
            "duration_s": self.duration_s,
            "sensors": self.sensors,
            "batches": self.batches,
            "wall_s": round(self.wall_s, 3),
            "realtime_factor": round(self.duration_s / max(self.wall_s, 1e-9), 2),
        }
        if self.tracker_ms_per_batch is not None:
            out["tracker_ms_per_batch"] = round(self.tracker_ms_per_batch, 4)
        out.update(self.metrics.to_dict())
        reach = self.reach
        seen, idf1 = (None, None) if reach is None else (reach.share(), reach.idf1())
        if seen is not None and idf1 is not None:
            out["seen"] = round(seen, 4)
            out["idf1_seen"] = round(idf1, 4)
        return out


def _drop_dont_care(hyp: Hypotheses, uncovered: np.ndarray, max_distance_m: float) -> Hypotheses:
    """Remove hypotheses that match present-but-uncovered people."""
    if len(uncovered) == 0 or len(hyp.ids) == 0:
        return hyp
    dist = np.linalg.norm(uncovered[:, None, :] - hyp.xy[None, :, :], axis=2)
    cost = np.where(dist <= max_distance_m, dist, 1e6)
    rows, cols = linear_sum_assignment(cost)
    drop = cols[cost[rows, cols] <= max_distance_m]
    keep = np.setdiff1d(np.arange(len(hyp.ids)), drop)
    return Hypotheses(hyp.ids[keep], hyp.xy[keep])


def evaluate(
    scenario: Scenario,
    feed: HypothesisFeed,
    *,
    max_distance_m: float = 0.5,
    ground_truth_rate_hz: float = 30.0,
    warmup_s: float = 0.0,
    on_frame: Callable[[float, GroundTruthFrame, Hypotheses | None], None] | None = None,
    sensor_model: str = "detections",
) -> EvalResult:
    """Run ``scenario`` through ``feed`` and score it.

    Parameters
    ----------
    scenario : Scenario
        What to simulate (must have a finite duration).
    feed : HypothesisFeed
        Source of hypotheses.
    max_distance_m : float
        Largest distance at which a hypothesis may correspond to a person.
    ground_truth_rate_hz : float
        Rate at which frames are scored.
    warmup_s : float
        Frames before this scenario time are not scored (the tracker may still be
        initialising tracks).
    on_frame : callable, optional
        Called with every scored frame (for plots and debugging).
    sensor_model : {"detections", "rgbd"}
        Sensor simulation level (``rgbd`` renders images and runs the detector).

    Raises
    ------
    ValueError
        If the scenario has no end.
    """
    if scenario.duration_s is None:
        raise ValueError("evaluate: the scenario needs a finite duration_s")
    sim = _simulator(scenario, ground_truth_rate_hz, sensor_model)
    acc = MotAccumulator(max_distance_m)
    reach = SensorReach()
    start = time.perf_counter()
    played = play(
        sim.events(),
        feed,
        acc,
        max_distance_m=max_distance_m,
        warmup_s=warmup_s,
        start_time=sim.start_time,
        on_frame=on_frame,
        reach=reach,
    )
    wall = time.perf_counter() - start
    return EvalResult(
        metrics=acc.compute(),
        scenario=scenario.name,
        seed=scenario.seed,
        duration_s=scenario.duration_s,
        sensors=len(scenario.sensors),
        batches=played.batches,
        wall_s=wall,
        tracker_ms_per_batch=tracker_ms_per_batch(feed),
        reach=reach,
    )


def _simulator(scenario: Scenario, ground_truth_rate_hz: float, sensor_model: str) -> Simulator:
    """The simulator for ``scenario`` (with the scenario's detector tuning for ``rgbd``)."""
    detector = None
    if sensor_model == "rgbd":
        from openptrack_py.eval.detector import detector_config_for

        detector = detector_config_for(scenario.name)
    return Simulator(
        scenario,
        ground_truth_rate_hz=ground_truth_rate_hz,
        sensor_model=sensor_model,
        detector_config=detector,
    )


@dataclass
class Played:
    """What :func:`play` went through.

    Parameters
    ----------
    batches : int
        Sensor frames fed.
    sensors : set of str
        Sensor ids seen.
    first_truth : float or None
        Time of the first ground-truth frame.
    last_truth : float or None
        Time of the last ground-truth frame.
    """

    batches: int = 0
    sensors: set[str] = field(default_factory=set)
    first_truth: float | None = None
    last_truth: float | None = None


def play(
    events: Iterable[Event],
    feed: HypothesisFeed,
    acc: MotAccumulator,
    *,
    max_distance_m: float = 0.5,
    warmup_s: float = 0.0,
    start_time: float | None = None,
    on_frame: Callable[[float, GroundTruthFrame, Hypotheses | None], None] | None = None,
    reach: SensorReach | None = None,
) -> Played:
    """Feed time-ordered events to ``feed``, scoring each ground-truth frame after the warm-up.

    Parameters
    ----------
    events : iterable of SensorFrame, TruthFrame or SensorsEnded
        The stream, in time order (sensor frames at their arrival time).
    feed : HypothesisFeed
        Source of hypotheses.
    acc : MotAccumulator
        Where the frames are scored.
    max_distance_m : float
        Largest distance at which a hypothesis may correspond to a person.
    warmup_s : float
        Ground-truth frames earlier than this after ``start_time`` are not scored.
    start_time : float, optional
        Start of the run; the first ground-truth frame's time when not given.
    on_frame : callable, optional
        Called with every scored frame.
    reach : SensorReach, optional
        Told of every sensor frame's people and every scored frame's covered people.

    Returns
    -------
    Played
        Counts of what was played.
    """
    played = Played()
    for event in events:
        if isinstance(event, SensorFrame):
            played.batches += 1
            played.sensors.add(event.batch.sensor_id)
            feed.on_sensor_frame(event)
            if reach is not None:
                reach.on_detections(event.time, event.person_ids)
            continue
        if isinstance(event, SensorsEnded):
            ended = getattr(feed, "on_sensors_ended", None)
            if ended is not None:
                ended()
            continue
        feed.on_truth_frame(event)
        if played.first_truth is None:
            played.first_truth = event.time
        played.last_truth = event.time
        origin = played.first_truth if start_time is None else start_time
        if event.time - origin < warmup_s:
            continue
        scored = _score_frame(event, feed, acc, max_distance_m, on_frame)
        if reach is not None:
            reach.on_truth(event.time, scored)
    return played


def _score_frame(
    event: TruthFrame,
    feed: HypothesisFeed,
    acc: MotAccumulator,
    max_distance_m: float,
    on_frame: Callable[[float, GroundTruthFrame, Hypotheses | None], None] | None,
) -> list[int]:
    """Score the feed's hypotheses against the covered people of one ground-truth frame.

    Returns the ids of the covered people scored.
    """
    people = event.frame.people
    covered = [p for p in people if p.covered]
    gt_ids = [p.id for p in covered]
    gt_xy = np.array([(p.x, p.y) for p in covered]).reshape(-1, 2)
    hyp = feed.hypotheses_at(event.time)
    if on_frame is not None:
        on_frame(event.time, event.frame, hyp)
    if hyp is None:
        acc.update_missing_frame(gt_ids, gt_xy, time_s=event.time)
        return gt_ids
    uncovered = np.array([(p.x, p.y) for p in people if not p.covered]).reshape(-1, 2)
    hyp = _drop_dont_care(hyp, uncovered, max_distance_m)
    acc.update(gt_ids, gt_xy, hyp.ids, hyp.xy, time_s=event.time)
    return gt_ids


def tracker_ms_per_batch(feed: HypothesisFeed) -> float | None:
    """Mean tracker step time in ms, when the feed ran a tracker that stepped."""
    if isinstance(feed, TrackerFeed) and feed.steps:
        return 1e3 * feed.step_seconds / feed.steps
    return None


def _cell(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.3f}"
    return "-" if value is None else str(value)


def format_table(rows: Sequence[dict[str, object]], columns: Sequence[str]) -> str:
    """Render result dicts as a fixed-width text table."""
    body = [[_cell(r.get(c)) for c in columns] for r in rows]
    widths = [max(len(c), *(len(b[i]) for b in body)) for i, c in enumerate(columns)]
    lines = ["  ".join(c.rjust(w) for c, w in zip(columns, widths, strict=True))]
    lines += ["  ".join(v.rjust(w) for v, w in zip(b, widths, strict=True)) for b in body]
    return "\n".join(lines)


def format_markdown(rows: Sequence[dict[str, object]], columns: Sequence[str]) -> str:
    """Render result dicts as a Markdown table."""
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(_cell(r.get(c)) for c in columns) + " |" for r in rows]
    return "\n".join(lines)
