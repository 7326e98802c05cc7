"""Accuracy regression: short seeded runs of every scenario must stay above their floors.

The floors in ``tests/golden/eval_floors.json`` were measured with the default tracker
(the full-length table with three seeds is in ``docs/evaluation.md``). Runs are
deterministic, so any drop comes from a change in the tracker or the simulator.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from openptrack_py.eval.trackers import run_eval
from openptrack_py.sim import SCENARIO_NAMES

FLOORS = json.loads((Path(__file__).parent / "golden" / "eval_floors.json").read_text())
FLOORS.pop("_comment")


def test_every_scenario_has_a_floor() -> None:
    assert sorted(FLOORS) == sorted(SCENARIO_NAMES)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", sorted(FLOORS), ids=str)
def test_tracking_accuracy_stays_above_the_floor(scenario: str) -> None:
    floor = FLOORS[scenario]
    result = run_eval(scenario, floor["seed"], duration_s=floor["duration_s"])
    m = result.metrics
    assert m.mota >= floor["mota"], f"{scenario}: MOTA {m.mota:.4f} < floor {floor['mota']}"
    assert m.idf1 >= floor["idf1"], f"{scenario}: IDF1 {m.idf1:.4f} < floor {floor['idf1']}"
    assert m.id_switches <= floor["max_id_switches"], (
        f"{scenario}: {m.id_switches} ID switches > {floor['max_id_switches']}"
    )
