"""The robustness sweep re-runs one tracker's rows and keeps the others'."""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks.sweep import main, merge_runs


def _row(tracker: str, seed: int, mota: float) -> dict[str, object]:
    return {"axis": "noise", "value": 1.0, "tracker": tracker, "seed": seed, "mota": mota}


def test_a_rerun_replaces_its_trackers_rows_and_keeps_the_others() -> None:
    old = [_row("ours", 11, 0.9), _row("norfair", 11, 0.8), _row("ours", 12, 0.7)]
    new = [_row("ours", 11, 0.95), _row("ours", 12, 0.75)]
    assert merge_runs(old, new) == [_row("norfair", 11, 0.8), *new]


def test_runs_of_other_seeds_or_lengths_are_not_merged(tmp_path: Path, capsys) -> None:
    out = tmp_path / "sweep"
    title = "crowd, realistic profile made worse one axis at a time; 30 s, seeds 1"
    out.with_suffix(".json").write_text(json.dumps({"title": title, "summary": {}, "runs": []}))
    assert main(["--trackers", "ours", "--merge", "--out", str(out)]) == 2
    assert "30 s, seeds 1', not" in capsys.readouterr().err
    assert json.loads(out.with_suffix(".json").read_text())["title"] == title  # untouched
