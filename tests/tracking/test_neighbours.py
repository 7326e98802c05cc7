"""Near and far pairs on the floor, against the all-pairs distances they avoid forming."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from openptrack_py.tracking.neighbours import close_pairs, count_within, far_pairs

_POINTS = st.integers(0, 12).flatmap(
    lambda n: st.lists(
        st.tuples(st.floats(-3.0, 3.0), st.floats(-3.0, 3.0)), min_size=n, max_size=n
    )
)


def _xy(points: list[tuple[float, float]]) -> np.ndarray:
    return np.array(points, dtype=float).reshape(-1, 2)


def _gaps(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)


@settings(max_examples=200, deadline=None)
@given(_POINTS, _POINTS, st.floats(0.0, 4.0), st.integers(0, 40))
def test_far_pairs_are_the_first_far_pairs_in_row_major_order(
    points: list[tuple[float, float]], to: list[tuple[float, float]], r: float, limit: int
) -> None:
    a, b = _xy(points), _xy(to)
    i, j = far_pairs(a, b, r, limit)
    d = a[:, None, :] - b[None, :, :]
    want_i, want_j = np.nonzero(d[..., 0] ** 2 + d[..., 1] ** 2 > r**2)
    np.testing.assert_array_equal(i, want_i[:limit])
    np.testing.assert_array_equal(j, want_j[:limit])


@settings(max_examples=200, deadline=None)
@given(_POINTS, _POINTS, st.floats(0.0, 4.0))
def test_count_within_counts_every_point_at_most_r_away(
    points: list[tuple[float, float]], to: list[tuple[float, float]], r: float
) -> None:
    a, b = _xy(points), _xy(to)
    gaps = _gaps(a, b)
    got = count_within(a, b, r)
    # a point within a rounding error of r may fall either side
    np.testing.assert_array_less((gaps < r - 1e-9).sum(axis=1) - 1, got)
    np.testing.assert_array_less(got - 1, (gaps <= r + 1e-9).sum(axis=1))


@settings(max_examples=100, deadline=None)
@given(_POINTS, st.floats(0.0, 4.0))
def test_close_pairs_are_every_pair_at_most_r_apart(
    points: list[tuple[float, float]], r: float
) -> None:
    a = _xy(points)
    i, j = close_pairs(a, r)
    gaps = _gaps(a, a)
    assert (i < j).all()
    assert (gaps[i, j] <= r + 1e-9).all()
    sure = np.argwhere(np.triu(gaps < r - 1e-9, 1))
    assert {tuple(p) for p in sure.tolist()} <= set(zip(i.tolist(), j.tolist(), strict=True))
