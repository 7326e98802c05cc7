"""The evaluation tables re-run the blocks asked for and keep the others' rows."""

from __future__ import annotations

import json

from benchmarks.eval_table import BLOCKS, EVALUATED, SUMMARY, main, plan, rows_path


def _rows() -> list[dict[str, object]]:
    return [
        {"block": block, "scenario": name, "seed": seed}
        for block, (_profile, seeds) in BLOCKS.items()
        for name in EVALUATED
        for seed in seeds
    ]


def test_every_block_runs_when_nothing_earlier_is_given() -> None:
    jobs, kept = plan(None, None)
    assert kept == []
    assert len(jobs) == 3 * 3 * len(EVALUATED)
    assert {j[0] for j in jobs} == set(BLOCKS)
    assert jobs[0][1] == "stress"  # the longest first
    assert {(j[0], j[3]) for j in jobs} == {
        ("robust", "realistic"),
        ("off", "realistic"),
        ("ideal", "ideal"),
    }


def test_earlier_rows_alone_are_the_whole_table() -> None:
    jobs, kept = plan(None, _rows())
    assert jobs == []
    assert kept == _rows()


def test_named_blocks_are_run_again_and_the_others_kept() -> None:
    jobs, kept = plan(["robust", "ideal"], _rows())
    assert {j[0] for j in jobs} == {"robust", "ideal"}
    assert len(jobs) == 2 * 3 * len(EVALUATED)
    assert kept == [r for r in _rows() if r["block"] == "off"]


def test_the_document_keeps_its_rows_at_full_precision_beside_it(tmp_path) -> None:
    rows = [
        {**r, "profile": "ideal" if r["block"] == "ideal" else "realistic",
         **dict.fromkeys(SUMMARY, 0.123456789), "id_switches": 3}
        for r in _rows()
    ]  # fmt: skip
    earlier = tmp_path / "rows.jsonl"
    earlier.write_text("".join(json.dumps(r) + "\n" for r in rows))
    out = tmp_path / "evaluation.md"
    main(["--rows", str(earlier), "--out", str(out)])
    assert "| crowd | 21 | 0.123 |" in out.read_text()  # the document rounds
    kept = [json.loads(x) for x in rows_path(out).read_text().splitlines()]
    assert rows_path(out).name == "evaluation_rows.jsonl"
    assert sorted(kept, key=json.dumps) == sorted(rows, key=json.dumps)  # the rows do not
