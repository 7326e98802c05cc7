"""Each sensor's error of the heights it measures, learned from the tracks it shares.

A sensor measures a person's height from the floor plane it was given. That plane is
a little off (a degree of tilt is 7 cm of height at 4 m), so one sensor's heights of
everyone sit a few centimetres above another's, more so far from it: between two
sensors, as much as heights differ between people. Compared as they come, a person
walking back in past another sensor would look like someone else.

:class:`HeightBias` learns each sensor's error as an affine function of the floor
position, ``a + b x + c y``, by least squares on the residuals of its detections
against the height models of the confirmed tracks they updated (models averaged over
every sensor that saw the person): the same quantity as the tracker's per-sensor
position bias, for heights. Old residuals fade, and a ridge term keeps the slope at 0
until the detections are spread enough to fix it. What all the sensors share (the
floor of the whole network a little high) cannot be learned this way, and needs not be:
heights are only ever compared with each other.
"""

from __future__ import annotations

import numpy as np

MEMORY = 2000.0
"""Residuals a sensor's estimate remembers (an old one weighs ``1/e`` after this many)."""
RIDGE = 10.0
"""Prior weight, in residuals at 1 m, that each coefficient is 0."""
MIN_RESIDUALS = 50.0
"""Residuals a sensor needs before its correction is applied."""


class HeightBias:
    """Per-sensor affine correction of measured heights."""

    def __init__(self) -> None:
        # sensor -> (A^T A (3, 3), A^T r (3,)) of rows (1, x, y), exponentially forgotten
        self._normal: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._coef: dict[str, np.ndarray] = {}

    def learn(self, sensor_id: str, xy: np.ndarray, residual: np.ndarray) -> None:
        """Add residuals ``residual (n,)`` (measured minus modelled height) at ``xy (n, 2)``."""
        if not len(residual):
            return
        ata, atb = self._normal.get(sensor_id, (np.zeros((3, 3)), np.zeros(3)))
        a = np.column_stack([np.ones(len(xy)), xy])
        fade = np.exp(-len(residual) / MEMORY)
        ata, atb = fade * ata + a.T @ a, fade * atb + a.T @ residual
        self._normal[sensor_id] = (ata, atb)
        if ata[0, 0] >= MIN_RESIDUALS:
            self._coef[sensor_id] = np.linalg.solve(ata + RIDGE * np.eye(3), atb)

    def correct(self, sensor_id: str, xy: np.ndarray, height: np.ndarray) -> np.ndarray:
        """Heights ``(n,)`` measured by ``sensor_id`` at ``xy (n, 2)``, corrected."""
        coef = self._coef.get(sensor_id)
        if coef is None or not len(height):
            return height
        return height - (coef[0] + xy @ coef[1:])

    def state(self) -> tuple[dict, dict]:
        """For snapshots (copies)."""
        return (
            {k: (a.copy(), b.copy()) for k, (a, b) in self._normal.items()},
            {k: c.copy() for k, c in self._coef.items()},
        )

    def restore(self, state: tuple[dict, dict]) -> None:
        """Return to a :meth:`state`."""
        normal, coef = state
        self._normal = {k: (a.copy(), b.copy()) for k, (a, b) in normal.items()}
        self._coef = {k: c.copy() for k, c in coef.items()}
