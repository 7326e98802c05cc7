"""Global nearest-neighbour association."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment


@dataclass(frozen=True)
class GlobalNearestNeighbour:
    """One-to-one track-detection pairs of minimum total cost among admissible pairs.

    Inadmissible pairs get a large finite cost so the solver first maximises the number
    of admissible pairs, then minimises their total cost; pairs the solver still picks
    among inadmissible ones are dropped.

    Parameters
    ----------
    forbidden_cost : float
        Cost given to inadmissible pairs; must exceed any sum of admissible costs.
    """

    forbidden_cost: float = 1.0e6

    def associate(self, cost: np.ndarray, allowed: np.ndarray) -> list[tuple[int, int]]:
        """Pairs ``(track_row, detection_column)``.

        Raises
        ------
        ValueError
            If an admissible cost is not finite.
        """
        if cost.size == 0 or not allowed.any():
            return []
        if not np.isfinite(cost[allowed]).all():
            raise ValueError("GlobalNearestNeighbour: admissible costs must be finite")
        filled = np.where(allowed, cost, self.forbidden_cost)
        rows, cols = linear_sum_assignment(filled)
        keep = allowed[rows, cols]
        return list(zip(rows[keep].tolist(), cols[keep].tolist(), strict=True))
