"""Hypothesis sources selectable by name in ``openptrack eval``, and the runs it makes.

:func:`run_eval` scores a tracker on a simulated scenario (with the simulator's noise
``profile`` where the simulator has profiles); :func:`run_file_eval` on ground truth and
detections read from files, or scores a tracks file (another tracker's output).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Sequence
from pathlib import Path

from openptrack_py.config import TrackerConfig, apply_overrides, read_yaml, validate_config
from openptrack_py.errors import ConfigError
from openptrack_py.eval.oracle import TruthFeed
from openptrack_py.eval.runner import EvalResult, HypothesisFeed, TrackerFeed, evaluate
from openptrack_py.sim.scenarios import Scenario, build_scenario
from openptrack_py.sim.simulator import DEFAULT_START_TIME
from openptrack_py.tracking import TrackingPipeline

FeedFactory = Callable[[Path | None, Sequence[str]], HypothesisFeed]


def load_tracker_config(path: Path | None = None, overrides: Sequence[str] = ()) -> TrackerConfig:
    """Tracker parameters from a YAML file, with ``key=value`` overrides.

    The file is a network file (its ``tracker:`` section is used) or the parameters
    themselves.

    Raises
    ------
    ConfigError
        Naming the key for unknown keys or invalid values.
    """
    data = read_yaml(path) if path is not None else {}
    if "tracker" in data and isinstance(data["tracker"], dict):
        data = data["tracker"]
    data = apply_overrides(dict(data), [o.removeprefix("tracker.") for o in overrides])
    return validate_config(TrackerConfig, data, str(path) if path else "tracker")


def tracking_feed(config: TrackerConfig) -> TrackerFeed:
    """A feed running the tracker of ``config`` behind its clock alignment and reorder."""
    return TrackerFeed(TrackingPipeline.from_config(config))


def _ukf(config: Path | None, overrides: Sequence[str]) -> HypothesisFeed:
    return tracking_feed(load_tracker_config(config, overrides))


def _truth(config: Path | None, overrides: Sequence[str]) -> HypothesisFeed:
    if config is not None or overrides:
        raise ConfigError("eval: the 'truth' oracle takes no tracker configuration")
    return TruthFeed(start_time=DEFAULT_START_TIME)


def _mcmc(config: Path | None, overrides: Sequence[str]) -> HypothesisFeed:
    from openptrack_py.tracking.mcmc import McmcTracker

    base = load_tracker_config(config, overrides)  # its reorder window and clock correction
    pipeline = TrackingPipeline(McmcTracker(), base.reorder_window_s, base.clock_correction)  # type: ignore[arg-type]
    return TrackerFeed(pipeline)


TRACKERS: dict[str, FeedFactory] = {"ukf": _ukf, "mcmc": _mcmc, "truth": _truth}
"""``ukf``: the tracker. ``mcmc``: the childcare paper's MCMC particle-group tracker
(:mod:`openptrack_py.tracking.mcmc`), for comparison. ``truth`` replays the ground
truth: it proves the harness."""
DEFAULT_TRACKER = "ukf"

DEFAULT_PROFILE = "realistic"
"""The profile trackers are evaluated on by default (when the simulator has profiles)."""


def simulator_has_profiles() -> bool:
    """Whether :func:`~openptrack_py.sim.scenarios.build_scenario` takes ``profile=``."""
    return "profile" in inspect.signature(build_scenario).parameters


def _feed(name: str | None, config: Path | None, overrides: Sequence[str]) -> HypothesisFeed:
    name = name or DEFAULT_TRACKER
    if name not in TRACKERS:
        raise ConfigError(f"eval: unknown tracker {name!r} (allowed: {', '.join(TRACKERS)})")
    return TRACKERS[name](config, overrides)


def run_eval(
    scenario: str | Scenario,
    seed: int = 0,
    *,
    duration_s: float | None = None,
    tracker: str | None = None,
    tracker_config: Path | None = None,
    overrides: Sequence[str] = (),
    max_distance_m: float = 0.5,
    sensor_model: str = "detections",
    profile: str | None = None,
) -> EvalResult:
    """Build ``scenario`` (unless given built) and evaluate the named tracker on it.

    ``sensor_model="rgbd"`` renders every sensor's images and runs the real detector on
    them instead of the detection-level sensor model. ``profile`` is the simulator's
    noise profile (``ideal``, ``realistic`` or ``harsh``); ``None`` passes none, so the
    simulator's own default applies.

    Raises
    ------
    ConfigError
        For an unknown scenario or tracker, an invalid tracker configuration, or a
        profile the simulator does not have.
    """
    feed = _feed(tracker, tracker_config, overrides)
    if isinstance(scenario, str):
        extra: dict[str, str] = {}
        if profile is not None:
            if not simulator_has_profiles():
                raise ConfigError(f"eval: this simulator has no noise profiles ({profile!r})")
            extra["profile"] = profile
        scenario = build_scenario(
            scenario, seed=seed, duration_s=-1.0 if duration_s is None else duration_s, **extra
        )
    elif profile is not None:
        raise ConfigError("eval: a profile applies to a scenario given by name, not one built")
    return evaluate(scenario, feed, max_distance_m=max_distance_m, sensor_model=sensor_model)


def run_file_eval(
    ground_truth: Path,
    *,
    detections: Path | None = None,
    tracks: Path | None = None,
    tracker: str | None = None,
    tracker_config: Path | None = None,
    overrides: Sequence[str] = (),
    latency_s: float = 0.0,
    max_distance_m: float = 0.5,
) -> EvalResult:
    """Score the named tracker on a detections file, or a tracks file, against ground truth.

    File formats: :mod:`openptrack_py.eval.external`. Give ``detections`` (our tracker,
    or the ``truth`` oracle, runs on them) or ``tracks`` (scored as they are), not both.

    Raises
    ------
    ConfigError
        For a malformed file (:class:`~openptrack_py.eval.external.ExternalFileError`,
        naming the file, line and column), an unknown tracker or an invalid
        configuration.
    """
    from openptrack_py.eval.external import TrackFileFeed, evaluate_files

    if (detections is None) == (tracks is None):
        raise ConfigError("eval: give detections or tracks to score against the ground truth")
    if tracks is not None:
        if tracker is not None or tracker_config is not None or overrides:
            raise ConfigError("eval: a tracks file is scored as it is: no tracker options")
        feed: HypothesisFeed = TrackFileFeed.from_file(tracks)
    else:
        feed = _feed(tracker, tracker_config, overrides)
    if latency_s < 0 or latency_s != latency_s:
        raise ConfigError(f"eval: latency must be >= 0 seconds, got {latency_s}")
    return evaluate_files(
        ground_truth,
        feed,
        detections=detections,
        latency_s=latency_s,
        max_distance_m=max_distance_m,
    )
