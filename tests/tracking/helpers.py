"""Hand-built detections and batches, and small oracles, shared by the tracking tests."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from openptrack_py.messages.detection import Detection, DetectionBatch
from openptrack_py.tracking import (
    Tracker,
)

H_POS = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
T0 = 1000.0  # start of hand-built batch streams
FRAME = 1.0 / 30.0


def det(x: float, y: float, conf: float = 0.9, distance: float = 3.0) -> Detection:
    return Detection(x=x, y=y, z=1.0, height=1.75, confidence=conf, distance=distance)


def make_batch(
    stamp: float, dets: Iterable[Detection] = (), sensor: str = "s0", seq: int = 0
) -> DetectionBatch:
    return DetectionBatch(
        sensor_id=sensor, seq=seq, stamp=stamp, frame_id="world", detections=tuple(dets)
    )


def feed_still(
    tracker: Tracker, xy: tuple[float, float], n: int, t0: float = T0, conf: float = 0.9
) -> float:
    """``n`` frames of one still person at ``xy``; returns the last stamp."""
    t = t0
    for k in range(n):
        t = t0 + k * FRAME
        tracker.step(make_batch(t, [det(*xy, conf=conf)], seq=k))
    return t


def is_spd(cov: np.ndarray) -> bool:
    sym = np.allclose(
        cov, np.swapaxes(cov, -1, -2), rtol=0.0, atol=1e-12 * max(1.0, abs(cov).max())
    )
    return bool(sym and (np.linalg.eigvalsh(cov) > 0).all())


def linear_kf(
    x: np.ndarray, p: np.ndarray, dt: float, q: float, z: np.ndarray | None, r: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """One textbook Kalman predict step, then an update when ``z`` is given."""
    f = np.eye(4)
    f[0, 2] = f[1, 3] = dt
    a, b, c = q * dt**3 / 3, q * dt**2 / 2, q * dt
    qm = np.array([[a, 0, b, 0], [0, a, 0, b], [b, 0, c, 0], [0, b, 0, c]])
    x = f @ x
    p = f @ p @ f.T + qm
    if z is None:
        return x, p
    s = H_POS @ p @ H_POS.T + r
    k = p @ H_POS.T @ np.linalg.inv(s)
    return x + k @ (z - H_POS @ x), p - k @ s @ k.T
