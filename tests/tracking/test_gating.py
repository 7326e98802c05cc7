"""The chi-square gate against scipy's quantiles and OpenPTrack's table."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from openptrack_py.tracking import (
    ChiSquareGater,
)

# ---------------------------------------------------------- chi-square gate


GATE_TABLE = [(p, dof) for p in (0.5, 0.9, 0.95, 0.99, 0.999, 0.99999) for dof in (2, 4)]


@pytest.mark.parametrize(("p", "dof"), GATE_TABLE, ids=[f"p{p}-dof{d}" for p, d in GATE_TABLE])
def test_gate_threshold_is_the_chi_square_quantile(p: float, dof: int) -> None:
    gater = ChiSquareGater(p, dof)
    assert gater.threshold == pytest.approx(chi2.ppf(p, dof), rel=1e-12)
    thr = gater.threshold
    assert gater.gate(np.array([0.0, thr * (1 - 1e-9), thr, thr * (1 + 1e-9)])).tolist() == [
        True,
        True,
        True,
        False,
    ]


@pytest.mark.parametrize(
    ("dof", "value"), [(2, 9.21), (4, 13.277)], ids=["openptrack-2dof", "openptrack-4dof"]
)
def test_gate_matches_openptrack_table_at_099(dof: int, value: float) -> None:
    assert ChiSquareGater(0.99, dof).threshold == pytest.approx(value, abs=2e-3)


@pytest.mark.parametrize(
    "p", [0.0, 1.0, -0.1, 1.5, math.nan, math.inf], ids=["0", "1", "neg", "gt1", "nan", "inf"]
)
def test_gate_rejects_bad_probability(p: float) -> None:
    with pytest.raises(ValueError, match="probability"):
        ChiSquareGater(p, 2)


@pytest.mark.parametrize("dof", [0, -1], ids=["0", "neg"])
def test_gate_rejects_bad_dof(dof: int) -> None:
    with pytest.raises(ValueError, match="dof"):
        ChiSquareGater(0.95, dof)
