"""Identity true positives (IDTP), the count behind IDF1, IDP and IDR.

Ground-truth trajectories are assigned one-to-one to hypothesis trajectories so that the
number of frames in which an assigned pair is within the gate is as large as possible
(Ristani et al., "Performance measures and a data set for multi-target, multi-camera
tracking", ECCV Workshops, 2016). That number is IDTP; IDF1 is
``2 IDTP / (gt_objects + hyp_objects)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment


def identity_true_positives(
    gt_uniq: NDArray[np.int64],
    gt_frames: NDArray[np.int64],
    hyp_uniq: NDArray[np.int64],
    hyp_frames: NDArray[np.int64],
    pair_gt: NDArray[np.int64],
    pair_hyp: NDArray[np.int64],
) -> int:
    """Return IDTP of the optimal one-to-one trajectory assignment.

    Parameters
    ----------
    gt_uniq, hyp_uniq : numpy.ndarray of int64
        Sorted distinct ground-truth and hypothesis ids.
    gt_frames, hyp_frames : numpy.ndarray of int64
        Number of frames each of those ids is present in.
    pair_gt, pair_hyp : numpy.ndarray of int64
        One entry per (frame, ground-truth object, hypothesis) within the gate: the two
        ids of the pair.

    Returns
    -------
    int
        The identity true positives.
    """
    if pair_gt.size == 0:
        return 0
    # Only trajectories with at least one gated frame can contribute identity true
    # positives; all others go to their dummy partner in any optimal assignment, so
    # leaving them out does not change IDTP and keeps the matrix small.
    g_act, g_idx = np.unique(np.searchsorted(gt_uniq, pair_gt), return_inverse=True)
    h_act, h_idx = np.unique(np.searchsorted(hyp_uniq, pair_hyp), return_inverse=True)
    n_g, n_h = g_act.size, h_act.size
    tp = np.bincount(g_idx * n_h + h_idx, minlength=n_g * n_h).reshape(n_g, n_h)
    g_len = gt_frames[g_act].astype(np.float64)
    h_len = hyp_frames[h_act].astype(np.float64)
    # (G + H) square cost: real gt rows x real hyp columns cost IDFN + IDFP of the pair;
    # a gt row may instead take its own dummy column (all its frames are IDFN), a hyp
    # column its own dummy row (all its frames are IDFP); dummy x dummy costs nothing.
    size = n_g + n_h
    cost = np.full((size, size), np.inf)
    cost[:n_g, :n_h] = g_len[:, None] + h_len[None, :] - 2.0 * tp
    cost[np.arange(n_g), n_h + np.arange(n_g)] = g_len
    cost[n_g + np.arange(n_h), np.arange(n_h)] = h_len
    cost[n_g:, n_h:] = 0.0
    rows, cols = linear_sum_assignment(cost)
    real = (rows < n_g) & (cols < n_h)
    return int(tp[rows[real], cols[real]].sum())
