"""Our tracker side by side with Stone Soup configured as the same model, on the same data.

Both trackers see the very same detections: the simulator's ``crowd`` scenario (7 people,
3 Kinect v2 at 30 Hz, 120 s) for seeds 0, 1, 2, played by
:func:`openptrack_py.eval.runner.evaluate` once per tracker (the simulator is
deterministic; a digest of every batch each tracker received is compared and reported
as ``same_detections``). Both are scored by the same harness (ground truth at 30 Hz,
0.5 m match distance, latest output extrapolated to the ground-truth time along each
track's velocity, output older than 1 s counts as missing): MOTA, MOTP, IDF1, ID
switches, false positives, misses.

Ours: :func:`openptrack_py.eval.trackers.tracking_feed` with the default
``TrackerConfig`` (clock alignment, 50 ms reorder window, UKF, chi-square gate, GNN,
lifecycle), exactly what ``openptrack eval`` runs. ``ms_per_batch`` is its mean time per
applied batch (pipeline push/poll and tracker steps, as timed by ``TrackerFeed``).

Stone Soup (1.9.x, through its public API only), a :class:`StoneSoupFeed` implementing
the harness's ``HypothesisFeed`` protocol. Every configuration choice:

* **Motion**: ``CombinedLinearGaussianTransitionModel`` of two ``ConstantVelocity(q)``
  with ``q = TrackerConfig().acceleration_variance`` (0.5 m^2/s^3). Stone Soup's
  ``ConstantVelocity.covar`` is ``q * [[dt^3/3, dt^2/2], [dt^2/2, dt]]`` per axis over
  ``|dt|``: continuous white-noise acceleration of spectral density ``q``, the same
  ``Q`` as our ``ConstantVelocity.noise``. The state order is Stone Soup's
  ``[x, vx, y, vy]``.
* **Filter**: ``UnscentedKalmanPredictor`` / ``UnscentedKalmanUpdater`` with
  ``alpha=1, beta=2, kappa=0``, our Merwe sigma-point parameters (Stone Soup's defaults
  are ``alpha=0.5, kappa=3-n``; with linear models every choice gives the same result).
* **Measurement**: ``LinearGaussian(ndim_state=4, mapping=(0, 2))``, isotropic with our
  noise at the typical range: ``sigma = measurement_sigma_m + measurement_sigma_per_m2 *
  d^2`` with ``d`` the median range of the crowd detections (6.3 m over the three
  seeds), i.e. 0.159 m. One model object shared by all detections (ours uses each
  detection's own range; a per-detection model would also defeat Stone Soup's
  measurement-prediction cache and make it slower).
* **Gate and cost**: ``DistanceHypothesiser(measure=Mahalanobis(), missed_distance=
  sqrt(chi2.ppf(gate_probability, 2)))`` = 2.448 for our 0.95. Stone Soup's
  ``Mahalanobis`` is the square root of the squared distance, hence the root of our
  chi-square gate; it is computed on the measurement prediction, whose covariance
  includes ``R``, like ours. Pairs beyond the gate are not hypothesised
  (``include_all=False``).
* **Association**: ``GNNWith2DAssignment`` (minimum total distance, a missed detection
  costing ``missed_distance``). Ours minimises ``d^2 + ln|S| - confidence`` instead.
* **Initiation and confirmation**: ``MultiMeasurementInitiator`` with ``min_points =
  detections_to_validate`` (3, the first detection included, like ours),
  ``updates_only=True``, its own GNN with the same hypothesiser, and a prior of
  ``initial_velocity_sigma_mps`` (1.5 m/s) on the velocity, zero mean (the position
  and its variance come from the detection, as ours). Only the tracks it releases,
  i.e. confirmed ones, enter the tracker and are published; its holding (tentative)
  tracks never are (as ours with ``publish_tentative: false``). Only detections at
  least ``min_confidence_initialization`` (0.5) confident are offered to the initiator
  (a small ``Initiator`` wrapper, :class:`ConfidentDetectionsOnly`); every detection
  is offered for association, as ours. Not reproduced: ours never starts a track from
  a detection inside an existing track's gate, and its tentative tracks take only the
  detections its confirmed tracks left.
* **Deletion** (our rules, as small ``Deleter`` subclasses): a holding track goes
  ``sec_before_fake`` (2.4 s) after its first detection (:class:`AgeDeleter`) or
  ``tentative_timeout_s`` (0.5 s) without a detection (:class:`LastUpdateDeleter`),
  the two joined by ``CompositeDeleter(..., intersect=False)``: ours deletes a
  tentative track on either rule. A confirmed
  track goes after ``sec_before_old`` (3 s) without an update by a detection at least
  ``min_confidence_initialization`` confident (:class:`LastUpdateDeleter`; ours: "only
  confident detections keep a track alive"). With Stone Soup's ``UpdateTimeDeleter``
  for both (``--stock-deleter``) a holding track lives as long as it keeps being
  updated, so it can collect three confident clutter hits over several seconds while
  its gate grows, and a confirmed ghost is then kept alive by low-confidence clutter
  in its wide gate: seed 0 gets a ghost track (139 false positives in the first
  20 s). That is a configuration choice, not Stone Soup's model. ``UpdateTimeDeleter``
  also walks a track's whole history on every check (``track[t - 3 s:]``), so Stone
  Soup's time per batch grew from 13 ms in the first 10 s to 82 ms in the last 10 s
  of seed 0 with it (flat 7-9 ms with :class:`LastUpdateDeleter`, which walks back
  from the newest state only).
* **Loop**: ``MultiTargetTracker.update_tracker(time, detections)`` once per
  ``DetectionBatch``, in arrival order, at the batch's stamp (Stone Soup has no
  reorder buffer; a batch captured before the previous one is predicted backwards,
  which its ``ConstantVelocity`` allows: ``F(dt)`` with ``Q(|dt|)``).
  Detections are ``Detection(StateVector([[x], [y]]), timestamp, measurement_model,
  metadata={"confidence": c})``.
* **Output**: after each batch the confirmed tracks' newest states (``x, y, vx, vy``) are
  kept with the batch's true capture time; ``hypotheses_at(t)`` extrapolates them along
  their velocity, exactly as ``TrackerFeed`` does for ours (including keeping the
  previous output after a batch captured earlier, and ``stale_after_s = 1``). Tracks
  without a confident update for longer than ``publish_unseen_s`` (0.5 s) are left out,
  as ours leaves out confirmed tracks unseen that long; ``--publish-unseen-s -1``
  publishes every confirmed track.
* **Timing**: Stone Soup's ``ms_per_batch`` is the mean time of ``update_tracker``
  alone; building the Stone Soup ``Detection`` objects is reported apart
  (``convert_ms_per_batch``) and is not in the speed ratio ``stonesoup_over_ours``
  (Stone Soup's ``ms_per_batch`` over ours).

Prints one JSON line: per seed and mean, for each tracker, MOTA, MOTP, IDF1, ID
switches, FP, FN and ms per batch, plus the speed ratio.

Run from the repository root::

    python -m benchmarks.bench_stonesoup [--seeds S ...] [--duration S] [--stock-deleter]
"""

from __future__ import annotations

import argparse
import hashlib
import math
import time
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone

import numpy as np
from stonesoup.base import Property
from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
from stonesoup.deleter.base import Deleter
from stonesoup.deleter.multi import CompositeDeleter
from stonesoup.deleter.time import UpdateTimeDeleter
from stonesoup.hypothesiser.distance import DistanceHypothesiser
from stonesoup.initiator.base import Initiator
from stonesoup.initiator.simple import MultiMeasurementInitiator
from stonesoup.measures import Mahalanobis
from stonesoup.models.measurement.linear import LinearGaussian
from stonesoup.models.transition.linear import (
    CombinedLinearGaussianTransitionModel,
    ConstantVelocity,
)
from stonesoup.predictor.kalman import UnscentedKalmanPredictor
from stonesoup.tracker.simple import MultiTargetTracker
from stonesoup.types.array import CovarianceMatrix, StateVector
from stonesoup.types.detection import Detection
from stonesoup.types.state import GaussianState
from stonesoup.types.update import Update
from stonesoup.updater.kalman import UnscentedKalmanUpdater

from benchmarks.common import emit
from openptrack_py.config import TrackerConfig
from openptrack_py.eval.runner import Hypotheses, TrackerFeed, evaluate
from openptrack_py.eval.trackers import tracking_feed
from openptrack_py.sim import SensorFrame, TruthFrame, build_scenario
from openptrack_py.tracking import ChiSquareGater

SEEDS = (0, 1, 2)
TYPICAL_RANGE_M = 6.3
"""Median range of the true detections of ``crowd`` seeds 0-2 (6.25, 6.39, 6.36 m)."""
METRICS = ("mota", "motp", "idf1", "id_switches", "fp", "fn")


class ConfidentDetectionsOnly(Initiator):
    """Offer only detections at least ``min_confidence`` confident to ``initiator``."""

    initiator: Initiator = Property(doc="The initiator that does the work.")
    min_confidence: float = Property(doc="Least detection confidence that may start a track.")

    def initiate(self, detections, timestamp, **kwargs):
        confident = {d for d in detections if d.metadata["confidence"] >= self.min_confidence}
        return self.initiator.initiate(confident, timestamp, **kwargs)


def last_update_time(track, min_confidence: float = 0.0) -> datetime | None:
    """Time of the newest update of ``track`` by a detection at least this confident.

    Walks back from the newest state, so it costs the states since that update only.
    """
    for state in reversed(track.states):
        if (
            isinstance(state, Update)
            and state.hypothesis
            and state.hypothesis.measurement.metadata.get("confidence", 1.0) >= min_confidence
        ):
            return state.timestamp
    return None


class LastUpdateDeleter(Deleter):
    """Delete a track not updated by a confident detection for ``time_since_update``.

    ``UpdateTimeDeleter``'s rule, with our "only confident detections keep a track
    alive", checked from the newest state backwards.
    """

    time_since_update: timedelta = Property(doc="Maximum time since the last update.")
    min_confidence: float = Property(default=0.0, doc="Least confidence of an update.")

    def check_for_deletion(self, track, timestamp=None, **kwargs):
        now = track.timestamp if timestamp is None else timestamp
        last = last_update_time(track, self.min_confidence)
        return last is None or now - last >= self.time_since_update


class AgeDeleter(Deleter):
    """Delete a track ``max_age`` after its first state (our tentative-track rule)."""

    max_age: timedelta = Property(doc="Longest life of a track.")

    def check_for_deletion(self, track, timestamp=None, **kwargs):
        now = track.timestamp if timestamp is None else timestamp
        return now - track.states[0].timestamp >= self.max_age


def measurement_sigma(cfg: TrackerConfig, distance_m: float = TYPICAL_RANGE_M) -> float:
    """Our position noise (standard deviation, metres) at ``distance_m``."""
    return cfg.measurement_sigma_m + cfg.measurement_sigma_per_m2 * distance_m**2


def missed_distance(cfg: TrackerConfig) -> float:
    """Our floor-position gate as a Mahalanobis distance (the root of its threshold)."""
    return math.sqrt(ChiSquareGater(cfg.gate_probability, 2).threshold)


def build_stonesoup(cfg: TrackerConfig, stock_deleter: bool = False) -> tuple:
    """A Stone Soup tracker with our model; returns ``(tracker, measurement_model)``."""
    q = cfg.acceleration_variance
    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(q), ConstantVelocity(q)])
    sigma = measurement_sigma(cfg)
    measurement = LinearGaussian(
        ndim_state=4, mapping=(0, 2), noise_covar=CovarianceMatrix(np.eye(2) * sigma**2)
    )
    sigma_points = {"alpha": 1.0, "beta": 2.0, "kappa": 0.0}
    predictor = UnscentedKalmanPredictor(transition, **sigma_points)
    updater = UnscentedKalmanUpdater(measurement, **sigma_points)
    hypothesiser = DistanceHypothesiser(
        predictor,
        updater,
        measure=Mahalanobis(),
        missed_distance=missed_distance(cfg),
    )
    fake, old = timedelta(seconds=cfg.sec_before_fake), timedelta(seconds=cfg.sec_before_old)
    if stock_deleter:
        holding_deleter, deleter = UpdateTimeDeleter(fake), UpdateTimeDeleter(old)
    else:
        # ours also drops a tentative track unseen for tentative_timeout_s
        unseen = LastUpdateDeleter(
            timedelta(seconds=cfg.tentative_timeout_s), cfg.min_confidence_initialization
        )
        holding_deleter = CompositeDeleter([AgeDeleter(fake), unseen], intersect=False)
        deleter = LastUpdateDeleter(old, cfg.min_confidence_initialization)
    v2 = cfg.initial_velocity_sigma_mps**2
    prior = GaussianState(
        StateVector([0.0, 0.0, 0.0, 0.0]), CovarianceMatrix(np.diag([0, v2, 0, v2]))
    )
    initiator = ConfidentDetectionsOnly(
        MultiMeasurementInitiator(
            prior_state=prior,
            deleter=holding_deleter,
            data_associator=GNNWith2DAssignment(hypothesiser),
            updater=updater,
            measurement_model=measurement,
            min_points=cfg.detections_to_validate,
            updates_only=True,
        ),
        cfg.min_confidence_initialization,
    )
    tracker = MultiTargetTracker(
        initiator=initiator,
        deleter=deleter,
        detector=None,
        data_associator=GNNWith2DAssignment(hypothesiser),
        updater=updater,
    )
    return tracker, measurement


def _stamp_to_datetime(stamp: float) -> datetime:
    return datetime.fromtimestamp(stamp, tz=timezone.utc)


def _digest_update(digest, frame: SensorFrame) -> None:
    b = frame.batch
    digest.update(f"{b.sensor_id}|{b.seq}|{b.stamp!r}|{frame.time!r}".encode())
    for d in b.detections:
        digest.update(f"|{d.x!r},{d.y!r},{d.confidence!r},{d.distance!r}".encode())


@dataclass
class StoneSoupFeed:
    """Runs Stone Soup on every sensor batch and reports its confirmed tracks.

    Parameters
    ----------
    config : TrackerConfig
        Parameters shared with our tracker.
    publish_unseen_s : float
        Leave out tracks whose last update is older; negative publishes all.
    stale_after_s : float
        Output older than this counts as no output (as ``TrackerFeed``).
    stock_deleter : bool
        Use Stone Soup's ``UpdateTimeDeleter`` for confirmed tracks.
    """

    config: TrackerConfig
    publish_unseen_s: float = 0.5
    stale_after_s: float = 1.0
    stock_deleter: bool = False
    steps: int = 0
    step_seconds: float = 0.0
    convert_seconds: float = 0.0
    digest: object = field(default_factory=hashlib.sha256)
    _latest: tuple[np.ndarray, np.ndarray] | None = None
    _latest_true_time: float = -float("inf")
    _ids: dict[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.tracker, self.measurement_model = build_stonesoup(self.config, self.stock_deleter)
        self._alive_confidence = (
            0.0 if self.stock_deleter else self.config.min_confidence_initialization
        )

    def on_sensor_frame(self, frame: SensorFrame) -> None:
        """Convert the batch, run one Stone Soup step (timed), keep its confirmed tracks."""
        _digest_update(self.digest, frame)
        start = time.perf_counter()
        when = _stamp_to_datetime(frame.batch.stamp)
        model = self.measurement_model
        detections = {
            Detection(
                StateVector([[d.x], [d.y]]),
                timestamp=when,
                measurement_model=model,
                metadata={"confidence": d.confidence},
            )
            for d in frame.batch.detections
        }
        mid = time.perf_counter()
        _, tracks = self.tracker.update_tracker(when, detections)
        end = time.perf_counter()
        self.convert_seconds += mid - start
        self.step_seconds += end - mid
        self.steps += 1
        if frame.capture_time < self._latest_true_time:
            return  # captured before the output we hold: keep that one (as TrackerFeed)
        ids, rows = [], []
        for track in tracks:
            if self.publish_unseen_s >= 0:
                last = last_update_time(track, self._alive_confidence)
                if last is None or (when - last).total_seconds() > self.publish_unseen_s:
                    continue
            x, vx, y, vy = np.asarray(track.state_vector, dtype=float).ravel()
            ids.append(self._ids.setdefault(track.id, len(self._ids) + 1))
            rows.append((x, y, vx, vy))
        self._latest = (np.array(ids, dtype=np.int64), np.array(rows).reshape(-1, 4))
        self._latest_true_time = frame.capture_time

    def on_truth_frame(self, frame: TruthFrame) -> None:
        """Stone Soup does not look at the truth."""

    def hypotheses_at(self, t: float) -> Hypotheses | None:
        """Latest confirmed tracks extrapolated to ``t`` along their velocity."""
        if self._latest is None:
            return None
        ids, rows = self._latest
        return Hypotheses.extrapolated(ids, rows, self._latest_true_time, t, self.stale_after_s)


@dataclass
class DigestingFeed:
    """Our ``TrackerFeed``, also hashing every batch it receives."""

    inner: TrackerFeed
    digest: object = field(default_factory=hashlib.sha256)

    def on_sensor_frame(self, frame: SensorFrame) -> None:
        _digest_update(self.digest, frame)
        self.inner.on_sensor_frame(frame)

    def on_truth_frame(self, frame: TruthFrame) -> None:
        self.inner.on_truth_frame(frame)

    def hypotheses_at(self, t: float) -> Hypotheses | None:
        return self.inner.hypotheses_at(t)


def _scores(metrics) -> dict[str, float | int]:
    d = metrics.to_dict()
    return {k: (round(d[k], 4) if isinstance(d[k], float) else d[k]) for k in METRICS}


def run_seed(
    seed: int, duration_s: float | None, publish_unseen_s: float, stock_deleter: bool
) -> dict[str, object]:
    cfg = TrackerConfig()
    scenario = build_scenario(
        "crowd", seed=seed, duration_s=-1.0 if duration_s is None else duration_s
    )

    ours_feed = DigestingFeed(tracking_feed(cfg))
    ours = evaluate(scenario, ours_feed)
    inner = ours_feed.inner
    ours_ms = 1e3 * inner.step_seconds / max(inner.steps, 1)

    ss_feed = StoneSoupFeed(cfg, publish_unseen_s=publish_unseen_s, stock_deleter=stock_deleter)
    ss = evaluate(scenario, ss_feed)
    ss_ms = 1e3 * ss_feed.step_seconds / max(ss_feed.steps, 1)
    return {
        "seed": seed,
        "duration_s": ours.duration_s,
        "batches": ours.batches,
        "same_detections": ours_feed.digest.hexdigest() == ss_feed.digest.hexdigest(),
        "ours": {**_scores(ours.metrics), "ms_per_batch": round(ours_ms, 4)},
        "stonesoup": {
            **_scores(ss.metrics),
            "ms_per_batch": round(ss_ms, 4),
            "convert_ms_per_batch": round(1e3 * ss_feed.convert_seconds / ss_feed.steps, 4),
        },
        "stonesoup_over_ours": round(ss_ms / ours_ms, 2),
    }


def _mean(rows: list[dict[str, object]], who: str) -> dict[str, float]:
    keys = [*METRICS, "ms_per_batch"]
    return {k: round(float(np.mean([r[who][k] for r in rows])), 4) for k in keys}


def main(
    seeds: tuple[int, ...] = SEEDS,
    duration_s: float | None = None,
    publish_unseen_s: float | None = None,
    stock_deleter: bool = False,
) -> dict[str, object]:
    cfg = TrackerConfig()
    unseen = cfg.publish_unseen_s if publish_unseen_s is None else publish_unseen_s
    rows = [run_seed(s, duration_s, unseen, stock_deleter) for s in seeds]
    mean_ours, mean_ss = _mean(rows, "ours"), _mean(rows, "stonesoup")
    return emit(
        "stonesoup_side_by_side",
        {
            "scenario": "crowd",
            "stonesoup_config": {
                "filter": "UKF alpha=1 beta=2 kappa=0",
                "q": cfg.acceleration_variance,
                "measurement_sigma_m": round(measurement_sigma(cfg), 4),
                "missed_distance": round(missed_distance(cfg), 4),
                "min_points": cfg.detections_to_validate,
                "holding_deleter": (
                    f"UpdateTimeDeleter({cfg.sec_before_fake} s)"
                    if stock_deleter
                    else f"AgeDeleter({cfg.sec_before_fake} s)"
                    f" or LastUpdateDeleter({cfg.tentative_timeout_s} s)"
                ),
                "deleter": (
                    f"UpdateTimeDeleter({cfg.sec_before_old} s)"
                    if stock_deleter
                    else f"LastUpdateDeleter({cfg.sec_before_old} s, "
                    f"confidence >= {cfg.min_confidence_initialization})"
                ),
                "publish_unseen_s": unseen,
                "min_confidence_initialization": cfg.min_confidence_initialization,
            },
            "seeds": rows,
            "mean": {
                "ours": mean_ours,
                "stonesoup": mean_ss,
                "stonesoup_over_ours": round(
                    mean_ss["ms_per_batch"] / mean_ours["ms_per_batch"], 2
                ),
            },
        },
    )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=list(SEEDS))
    parser.add_argument("--duration", type=float, default=None, help="seconds (default 120)")
    parser.add_argument(
        "--publish-unseen-s",
        type=float,
        default=None,
        help="hide Stone Soup tracks not updated for this long (default: ours, 0.5); <0: never",
    )
    parser.add_argument(
        "--stock-deleter", action="store_true", help="UpdateTimeDeleter for confirmed tracks"
    )
    args = parser.parse_args()
    main(tuple(args.seeds), args.duration, args.publish_unseen_s, args.stock_deleter)
