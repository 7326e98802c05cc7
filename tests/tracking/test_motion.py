"""The constant-velocity motion model."""

from __future__ import annotations

import numpy as np
import pytest

from openptrack_py.tracking import (
    ConstantVelocity,
)


def test_constant_velocity_noise_is_the_white_acceleration_discretisation() -> None:
    motion = ConstantVelocity(0.8)
    q = motion.noise(np.array([0.5, 2.0]))
    for qi, dt in zip(q, (0.5, 2.0), strict=True):
        block = 0.8 * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
        np.testing.assert_allclose(qi[np.ix_([0, 2], [0, 2])], block)
        np.testing.assert_allclose(qi[np.ix_([1, 3], [1, 3])], block)
        assert qi[0, 1] == qi[0, 3] == qi[2, 3] == 0.0
    with pytest.raises(ValueError, match="acceleration_variance"):
        ConstantVelocity(0.0)
