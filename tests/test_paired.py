"""The paired comparison of two tracker settings: seeds, statistics, one real run."""

from __future__ import annotations

import json

import numpy as np
import pytest

from benchmarks.paired import Job, main, paired_summary, parse_point, parse_seeds, run, summarise


def test_seeds_are_ranges_and_lists() -> None:
    assert parse_seeds("200-203") == [200, 201, 202, 203]
    assert parse_seeds("3, 10-12,3") == [3, 10, 11, 12]
    with pytest.raises(ValueError, match="'x' is not a seed"):
        parse_seeds("1,x")
    with pytest.raises(ValueError, match="'5-2' is not a range"):
        parse_seeds("5-2")


def test_the_sign_test_counts_seeds_that_got_better_and_worse() -> None:
    base = np.zeros(12)
    other = np.array([0.1] * 9 + [-0.1] + [0.0] * 2)
    s = paired_summary(base, other, higher_is_better=True)
    assert (s["better"], s["equal"], s["worse"]) == (9, 2, 1)
    # two-sided binomial: P(X <= 1) + P(X >= 9) for X ~ Bin(10, 1/2) = 22 / 1024
    assert s["sign_p"] == pytest.approx(22 / 1024)
    assert s["diff"] == pytest.approx(0.8 / 12)
    assert s["ci_low"] < s["diff"] < s["ci_high"]
    # for a count, fewer is better: the same differences are losses
    counts = paired_summary(base, other, higher_is_better=False)
    assert (counts["better"], counts["worse"]) == (1, 9)


def test_the_interval_is_the_same_every_run_and_collapses_on_equal_differences() -> None:
    rng = np.random.default_rng(4)
    a, b = rng.normal(size=30), rng.normal(size=30)
    assert paired_summary(a, b, True) == paired_summary(a, b, True)
    s = paired_summary(a, a + 0.25, True)
    assert s["ci_low"] == pytest.approx(0.25) and s["ci_high"] == pytest.approx(0.25)
    assert s["sign_p"] == pytest.approx(2 * 0.5**30)
    with pytest.raises(ValueError, match="equally long"):
        paired_summary([1.0, 2.0], [1.0], True)


def test_only_seeds_both_variants_ran_are_compared() -> None:
    rows = [
        {"scenario": "crowd", "seed": s, "variant": v, "mota": m, "idf1": m,
         "id_switches": 0, "duplicates": 0, "fp": 0, "fn": 0}
        for s, v, m in [(1, "base", 0.5), (1, "other", 0.7), (2, "base", 0.1)]
    ]  # fmt: skip
    mota = next(r for r in summarise(rows) if r["metric"] == "mota")
    assert mota["seeds"] == 1 and mota["diff"] == pytest.approx(0.2)


def test_a_real_comparison_prints_every_run_and_the_summary(capsys) -> None:
    main(["--scenario", "crowd", "--seeds", "1", "--duration", "2", "--jobs", "1",
          "--set", "merge_after_s=0"])  # fmt: skip
    out = capsys.readouterr().out.splitlines()
    runs = [json.loads(line) for line in out if line.startswith("{")]
    assert [r["variant"] for r in runs] == ["base", "other"]
    assert all(0.0 <= r["idf1"] <= 1.0 for r in runs)
    assert "| crowd | mota | 1 |" in "\n".join(out)


def test_the_same_settings_twice_are_refused(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["--scenario", "crowd", "--seeds", "1", "--set", "a=1", "--base-set", "a=1"])
    assert "nothing to compare" in capsys.readouterr().err


def test_a_sweep_point_is_an_axis_and_a_value() -> None:
    assert parse_point("calibration=0.2") == ("calibration", 0.2)
    with pytest.raises(ValueError, match="unknown axis 'wind'"):
        parse_point("wind=2")
    with pytest.raises(ValueError, match="'x' is not a number"):
        parse_point("noise=x")


def test_a_sweep_point_makes_the_detections_worse(capsys) -> None:
    plain = run(Job("crowd", 1, "realistic", 3.0, "base", ()))
    worse = run(Job("crowd", 1, "realistic", 3.0, "base", (), ("false_positives", 1.0)))
    assert worse["fp"] > plain["fp"]
    with pytest.raises(SystemExit):
        main(["--scenario", "crowd", "--seeds", "1", "--point", "noise=2", "--profile", "ideal",
              "--set", "merge_after_s=0"])  # fmt: skip
    assert "no --profile" in capsys.readouterr().err
