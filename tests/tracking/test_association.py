"""Global nearest-neighbour association against brute force."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from openptrack_py.tracking import (
    GlobalNearestNeighbour,
)

# -------------------------------------------------------- GNN association


def _brute_force(cost: np.ndarray, allowed: np.ndarray) -> tuple[int, float]:
    """Most admissible pairs, then least total cost, over all partial matchings."""
    n, m = cost.shape
    best = (0, 0.0)

    def walk(row: int, used: frozenset[int], count: int, total: float) -> None:
        nonlocal best
        if row == n:
            if count > best[0] or (count == best[0] and total < best[1]):
                best = (count, total)
            return
        walk(row + 1, used, count, total)  # row left unmatched
        for col in range(m):
            if allowed[row, col] and col not in used:
                walk(row + 1, used | {col}, count + 1, total + float(cost[row, col]))

    walk(0, frozenset(), 0, 0.0)
    return best


@st.composite
def _assignment_problems(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray]:
    n = draw(st.integers(0, 5))
    m = draw(st.integers(0, 5))
    cost = draw(arrays(np.float64, (n, m), elements=st.floats(-50.0, 50.0)))
    allowed = draw(arrays(np.bool_, (n, m)))
    poison = draw(st.sampled_from([None, math.nan, math.inf]))
    if poison is not None:  # what lies outside the gate must not matter
        cost = np.where(allowed, cost, poison)
    return cost, allowed


@settings(max_examples=300, deadline=None)
@given(_assignment_problems())
def test_gnn_equals_brute_force(problem: tuple[np.ndarray, np.ndarray]) -> None:
    cost, allowed = problem
    pairs = GlobalNearestNeighbour().associate(cost, allowed)
    rows = [r for r, _ in pairs]
    cols = [c for _, c in pairs]
    assert len(set(rows)) == len(rows)
    assert len(set(cols)) == len(cols)
    assert all(allowed[r, c] for r, c in pairs)
    count, total = _brute_force(cost, allowed)
    assert len(pairs) == count
    assert sum(float(cost[r, c]) for r, c in pairs) == pytest.approx(total, abs=1e-9)


@pytest.mark.parametrize("bad", [math.inf, -math.inf, math.nan], ids=["inf", "-inf", "nan"])
def test_gnn_rejects_non_finite_admissible_cost(bad: float) -> None:
    cost = np.array([[1.0, bad], [2.0, 3.0]])
    with pytest.raises(ValueError, match="finite"):
        GlobalNearestNeighbour().associate(cost, np.ones((2, 2), dtype=bool))
