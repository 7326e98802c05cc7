"""The analytics against ground truth: what a teacher reads, next to what happened.

:func:`tracked_and_true_frames` runs a scenario through a tracker and returns two streams
of :class:`~openptrack_py.analytics.frames.PeopleFrame` for the same instants: each
person's position as the tracker gave it (the hypothesis matched to them in that frame,
within ``max_distance_m``, as CLEAR MOT matches), and their true position, both only
where the tracker had them (a person nobody matched is missing from both). Analysing
both (:func:`~openptrack_py.analytics.analysis.analyze`) and comparing per person
measures the analytics' own error on tracked data — trajectory length, motion area,
relative distance — apart from misses and identity switches, which MOTA and IDF1
measure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from openptrack_py.analytics.analysis import Analysis, analyze
from openptrack_py.analytics.frames import PeopleFrame
from openptrack_py.eval.matching import max_matching_min_cost
from openptrack_py.eval.runner import EvalResult, Hypotheses, evaluate
from openptrack_py.eval.trackers import tracking_feed
from openptrack_py.messages.ground_truth import GroundTruthFrame
from openptrack_py.sim.scenarios import Scenario

__all__ = ["AnalyticsCheck", "check_analytics", "tracked_and_true_frames"]


def tracked_and_true_frames(
    scenario: Scenario,
    *,
    tracker_config: object = None,
    rate_hz: float = 10.0,
    max_distance_m: float = 0.5,
    kinds: dict[int, str] | None = None,
) -> tuple[list[PeopleFrame], list[PeopleFrame], EvalResult]:
    """The ground truth and the tracked positions of each person, ``rate_hz`` frames a second.

    ``kinds``, if given, is filled with each person's kind (``adult`` or ``child``).
    """
    from openptrack_py.config import TrackerConfig

    config = tracker_config if tracker_config is not None else TrackerConfig()
    feed = tracking_feed(config)  # type: ignore[arg-type]
    truth: list[PeopleFrame] = []
    tracked: list[PeopleFrame] = []
    period = 1.0 / rate_hz
    next_t = [-np.inf]

    def on_frame(t: float, gt: GroundTruthFrame, hyp: Hypotheses | None) -> None:
        if t < next_t[0]:
            return
        next_t[0] = t + 0.999 * period
        people = [p for p in gt.people if p.covered]
        if kinds is not None:
            kinds.update({p.id: p.kind for p in people})
        matched: dict[int, tuple[float, float]] = {}
        if hyp is not None and len(hyp.ids) and people:
            xy = np.array([(p.x, p.y) for p in people])
            dist = np.hypot(*(xy[:, None, :] - hyp.xy[None, :, :]).transpose(2, 0, 1))
            rows, cols = max_matching_min_cost(np.where(dist <= max_distance_m, dist, np.inf))
            for r, c in zip(rows, cols, strict=True):
                matched[people[r].id] = (float(hyp.xy[c, 0]), float(hyp.xy[c, 1]))
        tracked.append(PeopleFrame(t, matched))
        truth.append(PeopleFrame(t, {p.id: (p.x, p.y) for p in people if p.id in matched}))

    result = evaluate(scenario, feed, on_frame=on_frame, max_distance_m=max_distance_m)
    return truth, tracked, result


@dataclass
class AnalyticsCheck:
    """Per person and per pair: the analytics on tracked data and on the truth."""

    truth: Analysis
    tracked: Analysis
    result: EvalResult
    kinds: dict[int, str]

    def length_errors(self) -> dict[int, float]:
        """Relative error of each person's trajectory length."""
        return {
            k: self.tracked.people[k].length_m / p.length_m - 1.0
            for k, p in self.truth.people.items()
            if k in self.tracked.people and p.length_m > 0
        }

    def area_errors(self) -> dict[int, float]:
        """Relative error of each person's motion area (the bounding rectangle)."""
        return {
            k: self.tracked.people[k].bbox_area_m2 / p.bbox_area_m2 - 1.0
            for k, p in self.truth.people.items()
            if k in self.tracked.people and p.bbox_area_m2 > 0
        }

    def distance_errors(self) -> dict[tuple[int, int], float]:
        """Error of each pair's mean relative distance, metres."""
        return {
            key: self.tracked.pairs[key].mean_m - pair.mean_m
            for key, pair in self.truth.pairs.items()
            if key in self.tracked.pairs
        }


def check_analytics(scenario: Scenario, **options: object) -> AnalyticsCheck:
    """Analyse a scenario's truth and its tracked positions (see the module)."""
    kinds: dict[int, str] = {}
    truth, tracked, result = tracked_and_true_frames(scenario, kinds=kinds, **options)  # type: ignore[arg-type]
    return AnalyticsCheck(analyze(truth), analyze(tracked), result, kinds)
