"""Accuracy regression: short seeded runs of every scenario must stay above their floors.

The floors in ``tests/golden/eval_floors.json`` were measured with the default tracker on
both noise profiles (the full-length tables with three seeds are in
``docs/evaluation.md``). Runs are deterministic, so any drop comes from a change in the
tracker or the simulator.

All runs are made once, on every core, by a module fixture; each case then checks its own.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from openptrack_py.eval.metrics import MotMetrics
from openptrack_py.eval.trackers import run_eval
from openptrack_py.sim import SCENARIO_NAMES
from tests.cores import map_on_cores

FLOORS = json.loads((Path(__file__).parent / "golden" / "eval_floors.json").read_text())
FLOORS.pop("_comment")
CASES = [(profile, name) for profile, floors in sorted(FLOORS.items()) for name in sorted(floors)]


def _metrics(case: tuple[str, str]) -> MotMetrics:
    profile, scenario = case
    floor = FLOORS[profile][scenario]
    result = run_eval(scenario, floor["seed"], duration_s=floor["duration_s"], profile=profile)
    return result.metrics


@pytest.fixture(scope="module")
def measured() -> dict[tuple[str, str], MotMetrics]:
    """Every case's metrics, longest runs first so that both cores stay busy."""
    order = sorted(CASES, key=lambda c: -FLOORS[c[0]][c[1]]["duration_s"])
    return dict(zip(order, map_on_cores(_metrics, order), strict=True))


def test_every_scenario_has_a_floor_on_ideal() -> None:
    assert sorted(FLOORS["ideal"]) == sorted(SCENARIO_NAMES)


@pytest.mark.slow
@pytest.mark.parametrize(("profile", "scenario"), CASES, ids=[f"{p}-{s}" for p, s in CASES])
def test_tracking_accuracy_stays_above_the_floor(
    profile: str, scenario: str, measured: dict[tuple[str, str], MotMetrics]
) -> None:
    floor = FLOORS[profile][scenario]
    m = measured[(profile, scenario)]
    name = f"{scenario} ({profile})"
    assert m.mota >= floor["mota"], f"{name}: MOTA {m.mota:.4f} < floor {floor['mota']}"
    assert m.idf1 >= floor["idf1"], f"{name}: IDF1 {m.idf1:.4f} < floor {floor['idf1']}"
    assert m.id_switches <= floor["max_id_switches"], (
        f"{name}: {m.id_switches} ID switches > {floor['max_id_switches']}"
    )
    if "max_duplicates" in floor:
        assert m.duplicates <= floor["max_duplicates"], f"{name}: {m.duplicates} duplicates"
