"""Hypothesis sources selectable by name in ``openptrack eval``."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from openptrack_py.errors import ConfigError
from openptrack_py.eval.runner import EvalResult, HypothesisFeed, TruthFeed, evaluate
from openptrack_py.sim.scenarios import Scenario, build_scenario
from openptrack_py.sim.simulator import DEFAULT_START_TIME

FeedFactory = Callable[[Scenario, Path | None, Sequence[str]], HypothesisFeed]


def _truth(scenario: Scenario, config: Path | None, overrides: Sequence[str]) -> HypothesisFeed:
    if config is not None or overrides:
        raise ConfigError("eval: the 'truth' oracle takes no tracker configuration")
    return TruthFeed(start_time=DEFAULT_START_TIME)


TRACKERS: dict[str, FeedFactory] = {"truth": _truth}
"""``truth`` replays the ground truth: it proves the harness (it must score 1.0)."""
DEFAULT_TRACKER = "truth"


def run_eval(
    scenario: str,
    seed: int,
    *,
    duration_s: float | None = None,
    tracker: str | None = None,
    tracker_config: Path | None = None,
    overrides: Sequence[str] = (),
    max_distance_m: float = 0.5,
) -> EvalResult:
    """Build ``scenario`` and evaluate the named tracker on it.

    Raises
    ------
    ConfigError
        For an unknown scenario or tracker, or an invalid tracker configuration.
    """
    name = tracker or DEFAULT_TRACKER
    if name not in TRACKERS:
        raise ConfigError(f"eval: unknown tracker {name!r} (allowed: {', '.join(TRACKERS)})")
    built = build_scenario(
        scenario, seed=seed, duration_s=-1.0 if duration_s is None else duration_s
    )
    feed = TRACKERS[name](built, tracker_config, overrides)
    return evaluate(built, feed, max_distance_m=max_distance_m)
