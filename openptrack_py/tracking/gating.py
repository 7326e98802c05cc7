"""The chi-square gate on squared Mahalanobis distances."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2


@dataclass(frozen=True)
class ChiSquareGater:
    """Admit a track-detection pair when its squared Mahalanobis distance is small enough.

    The threshold is the ``probability`` quantile of the chi-square distribution with
    ``dof`` degrees of freedom: a correct detection falls inside the gate with that
    probability. (OpenPTrack compared the distance with the probability itself.)

    Parameters
    ----------
    probability : float
        Gate probability, in ``(0, 1)``.
    dof : int
        Measurement dimension.
    """

    probability: float
    dof: int
    threshold: float = field(init=False)

    def __post_init__(self) -> None:
        if not 0.0 < self.probability < 1.0:
            raise ValueError(
                f"ChiSquareGater: probability must be in (0, 1), got {self.probability}"
            )
        if isinstance(self.dof, bool) or not isinstance(self.dof, int) or self.dof < 1:
            raise ValueError(f"ChiSquareGater: dof must be an integer >= 1, got {self.dof!r}")
        object.__setattr__(self, "threshold", float(chi2.ppf(self.probability, self.dof)))

    def gate(self, d2: np.ndarray) -> np.ndarray:
        """Mask of admissible pairs."""
        return d2 <= self.threshold
