"""Hypothesis sources selectable by name in ``openptrack eval``."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from openptrack_py.config import TrackerConfig, apply_overrides, read_yaml, validate_config
from openptrack_py.errors import ConfigError
from openptrack_py.eval.runner import EvalResult, HypothesisFeed, TrackerFeed, TruthFeed, evaluate
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


TRACKERS: dict[str, FeedFactory] = {"ukf": _ukf, "truth": _truth}
"""``ukf``: the tracker. ``truth`` replays the ground truth: it proves the harness."""
DEFAULT_TRACKER = "ukf"


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
) -> EvalResult:
    """Build ``scenario`` (unless given built) and evaluate the named tracker on it.

    ``sensor_model="rgbd"`` renders every sensor's images and runs the real detector on
    them instead of the detection-level sensor model.

    Raises
    ------
    ConfigError
        For an unknown scenario or tracker, or an invalid tracker configuration.
    """
    name = tracker or DEFAULT_TRACKER
    if name not in TRACKERS:
        raise ConfigError(f"eval: unknown tracker {name!r} (allowed: {', '.join(TRACKERS)})")
    if isinstance(scenario, str):
        scenario = build_scenario(
            scenario, seed=seed, duration_s=-1.0 if duration_s is None else duration_s
        )
    feed = TRACKERS[name](tracker_config, overrides)
    return evaluate(scenario, feed, max_distance_m=max_distance_m, sensor_model=sensor_model)
