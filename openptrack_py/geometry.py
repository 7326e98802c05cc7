"""Rigid transforms between the world frame and a sensor's optical frame.

World frame: x, y on the floor, z up. Optical frame (as depth cameras deliver clouds):
x right, y down, z forward along the optical axis. A :class:`~openptrack_py.config.Pose`
gives the sensor's position, heading (yaw, counter-clockwise from +x), downward tilt
(pitch) and roll about the optical axis.
"""

from __future__ import annotations

import math

import numpy as np

from openptrack_py.config import Pose


def rotation_world_from_optical(yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """Rotation whose columns are the optical x (right), y (down), z (forward) in world axes."""
    yaw, pitch, roll = (math.radians(a) for a in (yaw_deg, pitch_deg, roll_deg))
    forward = np.array(
        [math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), -math.sin(pitch)]
    )
    right = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
    down = np.cross(forward, right)
    if roll:
        c, s = math.cos(roll), math.sin(roll)
        right, down = c * right + s * down, -s * right + c * down
    return np.column_stack([right, down, forward])


def world_from_optical(pose: Pose) -> np.ndarray:
    """4x4 homogeneous transform taking optical-frame points to the world frame."""
    transform = np.eye(4)
    transform[:3, :3] = rotation_world_from_optical(pose.yaw_deg, pose.pitch_deg, pose.roll_deg)
    transform[:3, 3] = (pose.x, pose.y, pose.z)
    return transform


def pose_from_transform(transform: np.ndarray) -> Pose:
    """The :class:`~openptrack_py.config.Pose` of a ``world_from_optical`` transform.

    Inverse of :func:`world_from_optical`. Looking straight down, heading and roll turn
    about the same axis: the roll is then 0 and the heading carries the rotation.
    """
    rot = np.asarray(transform, dtype=float)[:3, :3]
    right, forward = rot[:, 0], rot[:, 2]
    pitch = math.asin(float(np.clip(-forward[2], -1.0, 1.0)))
    if math.cos(pitch) > 1e-6:
        yaw = math.atan2(forward[1], forward[0])
        right0 = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
        down0 = np.cross(forward, right0)
        roll = math.atan2(float(right @ down0), float(right @ right0))
    else:
        yaw, roll = math.atan2(right[0], -right[1]), 0.0
    x, y, z = (float(v) for v in np.asarray(transform, dtype=float)[:3, 3])
    return Pose(
        x=x,
        y=y,
        z=z,
        yaw_deg=math.degrees(yaw),
        pitch_deg=math.degrees(pitch),
        roll_deg=math.degrees(roll),
    )


def invert(transform: np.ndarray) -> np.ndarray:
    """Inverse of a 4x4 rigid transform."""
    out = np.eye(4)
    rot = transform[:3, :3]
    out[:3, :3] = rot.T
    out[:3, 3] = -rot.T @ transform[:3, 3]
    return out


def apply(transform: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 4x4 transform to an ``(n, 3)`` array of points."""
    points = np.asarray(points, dtype=float)
    return points @ transform[:3, :3].T + transform[:3, 3]


def polygon_area(vertices: np.ndarray) -> float:
    """Area of a simple polygon given by its corners in order (shoelace formula).

    Parameters
    ----------
    vertices : array_like, shape (n, 2)
        Corners, clockwise or anticlockwise; fewer than three enclose nothing.

    Examples
    --------
    >>> polygon_area([[0, 0], [2, 0], [2, 1], [0, 1]])
    2.0
    """
    v = np.asarray(vertices, dtype=float).reshape(-1, 2)
    if len(v) < 3:
        return 0.0
    x, y = v[:, 0], v[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
