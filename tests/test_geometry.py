"""World <-> optical frame conventions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from openptrack_py.config import Pose
from openptrack_py.geometry import apply, invert, rotation_world_from_optical, world_from_optical


def test_level_camera_looking_along_x() -> None:
    rot = rotation_world_from_optical(0.0, 0.0, 0.0)
    right, down, forward = rot.T
    np.testing.assert_allclose(forward, [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(right, [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(down, [0, 0, -1], atol=1e-12)


@pytest.mark.parametrize(
    ("yaw", "pitch", "forward"),
    [
        (90.0, 0.0, [0, 1, 0]),
        (0.0, 90.0, [0, 0, -1]),
        (180.0, 45.0, [-np.sqrt(0.5), 0, -np.sqrt(0.5)]),
    ],
    ids=["yaw-left", "straight-down", "back-and-down"],
)
def test_forward_axis(yaw: float, pitch: float, forward: list[float]) -> None:
    np.testing.assert_allclose(
        rotation_world_from_optical(yaw, pitch, 0.0)[:, 2], forward, atol=1e-12
    )


def test_a_point_ahead_of_a_tilted_sensor() -> None:
    pose = Pose(x=1.0, y=2.0, z=2.5, yaw_deg=90.0, pitch_deg=30.0)
    # 2 m along the optical axis from the sensor
    point = apply(world_from_optical(pose), np.array([[0.0, 0.0, 2.0]]))[0]
    np.testing.assert_allclose(point, [1.0, 2.0 + 2 * np.cos(np.pi / 6), 2.5 - 1.0], atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(
    yaw=st.floats(-360, 360),
    pitch=st.floats(-90, 90),
    roll=st.floats(-180, 180),
    x=st.floats(-50, 50),
    y=st.floats(-50, 50),
    z=st.floats(0, 30),
)
def test_transforms_are_rigid_and_invertible(
    yaw: float, pitch: float, roll: float, x: float, y: float, z: float
) -> None:
    t = world_from_optical(Pose(x=x, y=y, z=z, yaw_deg=yaw, pitch_deg=pitch, roll_deg=roll))
    rot = t[:3, :3]
    np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(rot) == pytest.approx(1.0)
    np.testing.assert_allclose(invert(t) @ t, np.eye(4), atol=1e-9)
