"""Background learning and removal: a voxel occupancy set of the static scene.

For ``seconds`` after start-up every frame's points (in the floor-aligned frame) mark
their voxels as background; afterwards, points in a background voxel are removed before
clustering (Munaro et al., OpenPTrack, §5.4: its octree done as a sorted array of voxel keys).
"""

from __future__ import annotations

import numpy as np

_BITS = 21
_OFFSET = 1 << (_BITS - 1)


def voxel_keys(points: np.ndarray, resolution_m: float) -> np.ndarray:
    """One int64 key per point for its voxel (coordinates within about +-100 km)."""
    idx = np.floor(points / resolution_m).astype(np.int64) + _OFFSET
    return (idx[:, 0] << (2 * _BITS)) | (idx[:, 1] << _BITS) | idx[:, 2]


class BackgroundModel:
    """Learns the occupied voxels of the empty scene, then removes points inside them.

    Parameters
    ----------
    resolution_m : float
        Voxel size.
    learn_frames : int
        Frames to learn from.
    """

    def __init__(self, resolution_m: float = 0.1, learn_frames: int = 90) -> None:
        self.resolution_m = resolution_m
        self.learn_frames = learn_frames
        self.frames_seen = 0
        self._pending: list[np.ndarray] = []
        self._keys = np.zeros(0, dtype=np.int64)

    @property
    def learning(self) -> bool:
        """Whether the model is still learning."""
        return self.frames_seen < self.learn_frames

    @property
    def voxels(self) -> int:
        """Number of background voxels."""
        return len(self._keys)

    def learn(self, points: np.ndarray) -> None:
        """Add one frame's points to the background."""
        self._pending.append(np.unique(voxel_keys(points, self.resolution_m)))
        self.frames_seen += 1
        if not self.learning or len(self._pending) >= 16:
            self._keys = np.unique(np.concatenate([self._keys, *self._pending]))
            self._pending = []

    def foreground(self, points: np.ndarray) -> np.ndarray:
        """Mask of points outside the learned background."""
        if len(self._keys) == 0 or len(points) == 0:
            return np.ones(len(points), dtype=bool)
        keys = voxel_keys(points, self.resolution_m)
        pos = np.searchsorted(self._keys, keys)
        pos = np.minimum(pos, len(self._keys) - 1)
        return self._keys[pos] != keys
