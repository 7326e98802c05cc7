"""Looking keys up in a sorted array (track ids, floor cells, pooled identities).

``np.isin`` sorts both sides at every call; where one side is already sorted, a binary
search per key is all that is needed.
"""

from __future__ import annotations

import numpy as np


def find_sorted(sorted_keys: np.ndarray, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where each of ``keys`` is in the ascending ``sorted_keys``, and whether it is there.

    Returns positions (clipped into the array: meaningful only where found) and the
    found mask. ``sorted_keys`` must not be empty.
    """
    at = np.minimum(np.searchsorted(sorted_keys, keys), len(sorted_keys) - 1)
    return at, sorted_keys[at] == keys
