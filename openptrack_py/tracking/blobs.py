"""People standing so close that they come out as one detection: a shared blob.

The childcare tracking paper (section 2.3.3) lets several children share one detected
area. Here a confirmed track left without a detection may follow the detection of a
track the identity role knows to be another person standing beside it, so that neither
identity is dropped or swapped while they stand together. Two tracks that could both
have produced one detection also stop closing in on each other (:func:`slow_approaches`),
and two tracks known to be two people are never estimated closer than a body's depth
(:func:`keep_apart`).
"""

from __future__ import annotations

import numpy as np

from openptrack_py.tracking.base import IdentityModel
from openptrack_py.tracking.state import DetectionArrays, TrackTable

BLOB_RADIUS_M = 0.3
"""How far each of two people standing in one blob is from its centroid (half the
distance between two people side by side)."""
COLLISION_MISS_M = 0.3
"""Two people whose courses would pass closer than this, centre to centre, would walk
into each other (a shoulder width is about 0.4 m)."""


def share_blobs(
    tb: TrackTable,
    identity: IdentityModel,
    dets: DetectionArrays,
    rows: np.ndarray,
    cols: np.ndarray,
    d2: np.ndarray,
    gated: np.ndarray,
    t: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs plus the tracks that share a blob with another person's track.

    People standing close together come out as one detection (the childcare
    tracking paper, section 2.3.3: several children may share one detected area).
    A confirmed track left without a detection whose nearest gated detection went to
    a track the identity role knows to be *another person* is updated by that
    detection too (weakly, see ``shared_noise_factor``), so neither identity is lost
    while they stand together (for as long as the identity role allows: see
    :meth:`~openptrack_py.tracking.base.IdentityModel.shares`). Without an identity
    opinion nothing is shared, and nothing is shared by a track with a detection
    nobody took within a blob's width (the blob has parted: that may be its person).
    Returns rows, columns and which pairs are such shares.
    """
    idle = np.ones(len(tb), dtype=bool)
    idle[rows] = False
    idle &= tb.confirmed & gated[:, cols].any(axis=1)
    none = np.zeros(len(rows), dtype=bool)
    if not idle.any():
        return rows, cols, none
    lonely = np.flatnonzero(idle)
    left = np.setdiff1d(np.arange(len(dets)), cols)
    if len(left):
        gap = np.linalg.norm(tb.x[lonely, None, 0:2] - dets.xy[None, left], axis=2)
        lonely = lonely[(gap > 2 * BLOB_RADIUS_M).all(axis=1)]
        if not len(lonely):
            return rows, cols, none
    near = np.argmin(np.where(gated[np.ix_(lonely, cols)], d2[np.ix_(lonely, cols)], np.inf), 1)
    partner = rows[near]
    two = identity.shares(tb, lonely, partner, dets, cols[near], t) & tb.confirmed[partner]
    if not two.any():
        return rows, cols, none
    extra_rows, extra_cols = lonely[two], cols[near[two]]
    flags = np.concatenate([none, np.ones(len(extra_rows), dtype=bool)])
    return np.concatenate([rows, extra_rows]), np.concatenate([cols, extra_cols]), flags


def shared_noise(
    r: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    blob: np.ndarray,
    gated: np.ndarray,
    confirmed: np.ndarray,
    factor: float,
    nll: np.ndarray | None = None,
) -> np.ndarray:
    """The noise ``r (n, dim, dim)`` of each pair's detection, widened where it is shared.

    A detection two confirmed tracks could both have produced may be either person, or
    both in one blob: it pulls its track less, so neither is dragged onto the other's
    course. By how much follows probabilistic data association (Bar-Shalom and Tse,
    1975): the detection is the pair's track's with probability ``beta``, its
    likelihood under that track over the sum of its likelihoods under every confirmed
    track whose gate it is in (``nll (n_tracks, n_detections)``: the association's cost,
    minus twice each pair's log Gaussian likelihood up to a term per detection, which
    cancels), and its noise is divided by ``beta``, never widened more than ``factor``.
    A detection exactly between two tracks counts half; one that is plainly its own
    track's counts whole. Without ``nll`` every shared detection is
    widened by ``factor``. A detection explicitly shared (``blob``) is widened by
    ``factor`` and gets a body radius of extra uncertainty for every track it updates,
    since each person is up to that far from the blob's centroid: both tracks stay
    ready for the two detections when they part.
    """
    out = r
    if factor > 1.0:
        rivals = gated[:, cols] & confirmed[:, None]
        shared = rivals.sum(axis=0) >= 2
        widen = np.where(blob | shared, factor, 1.0)
        if nll is not None and shared.any():
            # one of several people, not several in one blob: every rival has its own
            taken = np.zeros(len(gated), dtype=bool)
            taken[rows[~blob]] = True
            one = shared & ~blob & ~(rivals & ~taken[:, None]).any(axis=0)
            beta = _own_share(nll, rows[one], cols[one], rivals[:, one])
            widen[one] = 1.0 / np.maximum(beta, 1.0 / factor)
        if (widen > 1.0).any():
            out = out * widen[:, None, None]
    if blob.any():
        in_blob = np.isin(cols, cols[blob])
        out = out.copy()
        out[in_blob, 0:2, 0:2] += BLOB_RADIUS_M**2 * np.eye(2)
    return out


def _own_share(
    nll: np.ndarray, rows: np.ndarray, cols: np.ndarray, rivals: np.ndarray
) -> np.ndarray:
    """Probability that detection ``cols[k]`` is track ``rows[k]``'s, among ``rivals[:, k]``.

    Each track's odds are its likelihood, ``exp(-nll / 2)`` (``nll`` is ``(n_tracks,
    n_detections)``), computed for these detections only; the pair's own track counts
    once whether or not it is among the rivals.
    """
    ll = np.where(rivals, -0.5 * nll[:, cols], -np.inf)
    ll[rows, np.arange(len(cols))] = -0.5 * nll[rows, cols]
    top = ll.max(axis=0)
    odds = np.exp(ll - top)
    return odds[rows, np.arange(len(cols))] / odds.sum(axis=0)


def slow_approaches(tb: TrackTable, gated: np.ndarray, dt: float, stop_s: float) -> None:
    """Slow down confirmed tracks on a collision course within one detection's reach.

    Two confirmed tracks gated to one detection belong to people close enough for one
    blob. People about to walk into each other slow down and step aside rather than walk
    through each other (the social force model, Helbing and Molnar, 1995), and a
    detection that may be either of them, or both, says little about who went where. So
    when their courses would pass within :data:`COLLISION_MISS_M`, the component of
    their relative velocity that brings them together decays with time constant
    ``stop_s`` over ``dt``, shared equally (their mean velocity is kept). Walking side
    by side, parting, or passing each other a body apart is left alone.
    """
    if stop_s <= 0 or dt <= 0 or len(tb) < 2:
        return
    near = (gated & tb.confirmed[:, None]).astype(np.int64)
    if not (near.sum(axis=0) >= 2).any():
        return
    a, b = np.nonzero(np.triu(near @ near.T, 1))
    gap = tb.x[b, 0:2] - tb.x[a, 0:2]
    norm = np.linalg.norm(gap, axis=1)
    keep = norm > 1e-6
    a, b, gap, norm = a[keep], b[keep], gap[keep], norm[keep]
    rel = tb.x[a, 2:4] - tb.x[b, 2:4]  # how fast a goes towards b
    toward = np.einsum("ij,ij->i", rel, gap)
    # centre-to-centre distance at their closest approach, if they kept walking
    until = toward / np.maximum(np.einsum("ij,ij->i", rel, rel), 1e-12)
    miss = np.linalg.norm(gap - rel * until[:, None], axis=1)
    closing = np.where(miss < COLLISION_MISS_M, np.maximum(toward / norm, 0.0), 0.0)
    cut = (0.5 * (1.0 - np.exp(-dt / stop_s)) * closing / norm)[:, None] * gap
    np.subtract.at(tb.x, (a, slice(2, 4)), cut)
    np.add.at(tb.x, (b, slice(2, 4)), cut)


def keep_apart(tb: TrackTable, a: np.ndarray, b: np.ndarray, gap_m: float) -> None:
    """Push the estimates of tracks ``a[k]`` and ``b[k]`` (two people) ``gap_m`` apart.

    Two people's centres are never closer than a body's depth. Where the estimates of a
    pair known to be two people are, they are projected onto that constraint the way a
    Kalman estimate is projected onto a state constraint (Simon and Chia, "Kalman
    filtering with state equality constraints", 2002): along the unit vector ``u``
    between them, ``x_a -= lam P_a[:, :2] u`` and ``x_b += lam P_b[:, :2] u`` with
    ``lam = (gap_m - d) / (u' P_a u + u' P_b u)``, so the more uncertain track moves
    more, its velocity moves with its position (their covariance), and their order
    along ``u`` is kept. Covariances are left as they are. Pairs are taken in turn (a
    track pushed by one neighbour may be pushed back by the next).
    """
    if gap_m <= 0 or not len(a):
        return
    d = tb.x[b, 0:2] - tb.x[a, 0:2]
    n = np.hypot(d[:, 0], d[:, 1])
    near = np.flatnonzero((n < gap_m) & (n > 1e-9))  # coincident: no side to push to
    for k in near.tolist():
        i, j = int(a[k]), int(b[k])
        gap = tb.x[j, 0:2] - tb.x[i, 0:2]
        dist = float(np.hypot(*gap))
        if dist >= gap_m or dist <= 1e-9:
            continue
        u = gap / dist
        pa = tb.cov[i, :, 0:2] @ u
        pb = tb.cov[j, :, 0:2] @ u
        lam = (gap_m - dist) / max(float(u @ pa[0:2] + u @ pb[0:2]), 1e-12)
        tb.x[i] -= lam * pa
        tb.x[j] += lam * pb
