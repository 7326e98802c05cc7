"""Per-frame inputs of the metrics: validated ids and positions, gated distances, pairing.

Ground truth and tracker output are compared with Euclidean distances in metres; a pair
farther apart than the gate ``max_distance_m`` cannot correspond. The pairing used for
the objects left over after the CLEAR MOT "keep the previous match" step is a linear
assignment restricted to pairs within the gate: the largest possible number of pairs,
and among those the smallest total distance.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

EMPTY_IDS: NDArray[np.int64] = np.empty(0, dtype=np.int64)
"""A frame's ids when nobody is there."""


def check_max_distance(max_distance_m: float) -> float:
    """Validate the matching threshold and return it as a float.

    Raises
    ------
    ValueError
        If ``max_distance_m`` is not a finite number > 0.
    """
    message = f"max_distance_m must be a finite number > 0 (metres); got {max_distance_m!r}"
    if isinstance(max_distance_m, bool):
        raise ValueError(message)
    try:
        value = float(max_distance_m)
    except (TypeError, ValueError):
        raise ValueError(message) from None
    if not math.isfinite(value) or value <= 0.0:
        raise ValueError(message)
    return value


def as_ids(ids: ArrayLike, name: str) -> NDArray[np.int64]:
    """Validate one frame's ids: a 1-D sequence of distinct integers.

    Parameters
    ----------
    ids : sequence of int
        The ids.
    name : str
        The argument's name, for errors.

    Returns
    -------
    numpy.ndarray of int64
        The ids (:data:`EMPTY_IDS` when there are none).

    Raises
    ------
    ValueError
        If the ids are not 1-D integers in the int64 range or repeat.
    """
    try:
        arr = np.asarray(ids)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a sequence of integers; got {ids!r}") from exc
    if arr.size == 0:
        if arr.ndim > 1 and arr.shape[-1] != 0:
            raise ValueError(f"{name} must be 1-D; got shape {arr.shape}")
        return EMPTY_IDS
    if arr.ndim != 1:
        raise ValueError(f"{name} must be 1-D; got shape {arr.shape}")
    if arr.dtype.kind not in "iu":
        raise ValueError(f"{name} must contain integers; got dtype {arr.dtype}")
    if arr.dtype.kind == "u" and int(arr.max()) > np.iinfo(np.int64).max:
        raise ValueError(f"{name} contains ids larger than the int64 range")
    arr = arr.astype(np.int64, copy=False)
    if np.unique(arr).size != arr.size:
        values, counts = np.unique(arr, return_counts=True)
        duplicates = values[counts > 1].tolist()
        raise ValueError(f"{name} must be unique within a frame; duplicated ids: {duplicates}")
    return arr


def as_points(
    xy: ArrayLike, name: str, n: int | None = None, ids_name: str = ""
) -> NDArray[np.float64]:
    """Validate coordinates: shape (n, 2) or (n, 3), finite, in metres.

    Parameters
    ----------
    xy : array_like
        The positions.
    name : str
        The argument's name, for errors.
    n : int, optional
        The number of rows required (the number of ids), if any.
    ids_name : str
        The name of the ids argument, for the error when ``n`` does not match.

    Returns
    -------
    numpy.ndarray of float64, shape (n, 2) or (n, 3)
        The positions (an empty 1-D input becomes shape (0, 2)).

    Raises
    ------
    ValueError
        If the shape is wrong, the row count differs from ``n`` or a value is not finite.
    """
    try:
        arr = np.asarray(xy, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be an array of shape (n, 2) or (n, 3): {exc}") from exc
    if arr.ndim == 1 and arr.size == 0:
        arr = arr.reshape(0, 2)
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ValueError(f"{name} must have shape (n, 2) or (n, 3); got shape {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise ValueError(
            f"{name} has {arr.shape[0]} rows but {ids_name} has {n} ids; "
            "they must have the same length"
        )
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} contains non-finite coordinates (NaN or inf)")
    return arr


def pairwise_distances(gt: NDArray[np.float64], hyp: NDArray[np.float64]) -> NDArray:
    """Euclidean distances between validated point sets of equal dimension.

    Returns
    -------
    numpy.ndarray, shape (len(gt), len(hyp))
        Distances in metres, ungated.
    """
    diff = gt[:, None, :] - hyp[None, :, :]
    return np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))


def distance_matrix(
    gt_xy: ArrayLike, hyp_xy: ArrayLike, max_distance_m: float
) -> NDArray[np.float64]:
    """Compute gated Euclidean distances between ground-truth objects and hypotheses.

    Parameters
    ----------
    gt_xy : array_like, shape (n, 2) or (n, 3)
        Ground-truth positions in metres; ``n`` may be 0.
    hyp_xy : array_like, shape (m, 2) or (m, 3)
        Hypothesis positions in metres; ``m`` may be 0. When both are non-empty they must
        have the same number of coordinates; all of them are used.
    max_distance_m : float
        Gate in metres, finite and > 0. A distance equal to the gate is kept.

    Returns
    -------
    numpy.ndarray, shape (n, m)
        Distances in metres, ``numpy.inf`` where the distance exceeds ``max_distance_m``.

    Raises
    ------
    ValueError
        If an argument has the wrong shape, contains non-finite coordinates, or the gate
        is not a finite positive number.
    """
    gate = check_max_distance(max_distance_m)
    gt = as_points(gt_xy, "gt_xy")
    hyp = as_points(hyp_xy, "hyp_xy")
    if gt.shape[0] == 0 or hyp.shape[0] == 0:
        return np.empty((gt.shape[0], hyp.shape[0]), dtype=np.float64)
    if gt.shape[1] != hyp.shape[1]:
        raise ValueError(
            "gt_xy and hyp_xy must have the same number of coordinates; "
            f"got {gt.shape[1]} and {hyp.shape[1]}"
        )
    dist = pairwise_distances(gt, hyp)
    dist[dist > gate] = np.inf
    return dist


def max_matching_min_cost(cost: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Pair rows and columns through finite, non-negative entries of ``cost``.

    The result has the largest possible number of pairs and, among such matchings, the
    smallest total cost. Infinite entries are forbidden pairs.

    Returns
    -------
    rows, cols : numpy.ndarray of int
        Row and column indices of the pairs.
    """
    allowed = np.isfinite(cost)
    rows = np.flatnonzero(allowed.any(axis=1))
    cols = np.flatnonzero(allowed.any(axis=0))
    if rows.size == 0:
        return EMPTY_IDS, EMPTY_IDS
    sub = cost[np.ix_(rows, cols)]
    sub_allowed = allowed[np.ix_(rows, cols)]
    # scipy assigns min(shape) pairs, so forbidden pairs get a finite penalty larger than
    # the total cost of any set of allowed pairs: one more allowed pair always lowers the
    # objective, hence cardinality is maximised first and the cost second.
    size = min(sub.shape)
    penalty = size * (float(sub[sub_allowed].max()) + 1.0)
    r, c = linear_sum_assignment(np.where(sub_allowed, sub, penalty))
    keep = sub_allowed[r, c]
    return rows[r[keep]], cols[c[keep]]
