"""Each sensor's error of the heights it measures, learned from the people sensors share.

A sensor measures a person's height from the floor plane it was given. That plane is
a little off (a degree of tilt is 7 cm of height at 4 m), so one sensor's heights of
everyone sit a few centimetres above another's, more so far from it: between two
sensors, as much as heights differ between people. Compared as they come, a person
walking back in past another sensor would look like someone else.

:class:`HeightBias` learns each sensor's error as an affine function of the floor
position, ``a + b x + c y``, by least squares on residuals: a sensor's height of a
track against the same track's heights from the *other* sensors that saw it within
:data:`RECENT_S`, corrected. Against the track's height model instead (the average of
every sensor's heights, its own included) each residual holds only the share of the
error the other sensors' heights make visible, and a sensor that sees a part of the
room alone (a door) never learns its error there; on a ``reentry`` run (seed 32) a
sensor whose floor added 5-10 cm by the door had learned a correction of the wrong
sign there, and people coming back measured 13-20 cm taller than when they left. Old
residuals fade, and a ridge term keeps the slope at 0 until the detections are spread
enough to fix it.

What all the sensors share (the floor of the whole network a little high) cannot be
learned from their differences. Each sensor's floor is calibrated on its own, so their
errors are independent and their best shared estimate is none: the corrections are
held to a weighted mean of 0 over the detections they were learned from, and remove
only the sensors' differences (left free, that shared part drifts).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from openptrack_py.tracking.lookup import find_sorted

MEMORY = 2000.0
"""Residuals a sensor's estimate remembers (an old one weighs ``1/e`` after this many)."""
RIDGE = 10.0
"""Prior weight, in residuals at 1 m, that each coefficient is 0."""
MIN_RESIDUALS = 50.0
"""Residuals a sensor needs before its correction is applied."""
RECENT_S = 1.0
"""How long another sensor's height of a track is a reference for this one's (the
person's height does not change; a gait's bob is noise within it)."""


class HeightBias:
    """Per-sensor affine correction of measured heights."""

    def __init__(self) -> None:
        # sensor -> (A^T A (3, 3), A^T r (3,)) of rows (1, x, y), exponentially forgotten
        self._normal: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._coef: dict[str, np.ndarray] = {}
        self._shared = 0.0  # the corrections' weighted mean, removed from each
        # sensor -> rows (track id, time, raw height, x, y) of the tracks it saw within
        # RECENT_S, one per track, sorted by id
        self._recent: dict[str, np.ndarray] = {}

    def learn(
        self, sensor_id: str, track_ids: np.ndarray, xy: np.ndarray, raw: np.ndarray, t: float
    ) -> None:
        """Add ``sensor_id``'s raw heights ``(n,)`` at ``xy (n, 2)`` of tracks ``track_ids``.

        Each is compared with the same track's heights from other sensors within
        :data:`RECENT_S` of ``t`` (corrected), and kept as a reference for them.
        """
        ids = np.asarray(track_ids, dtype=float)
        total, count = np.zeros(len(ids)), np.zeros(len(ids))
        for sensor, rec in self._recent.items():
            if sensor == sensor_id or not len(rec):
                continue
            k, found = find_sorted(rec[:, 0], ids)
            hit = found & (t - rec[k, 1] <= RECENT_S)
            total += np.where(hit, rec[k, 2] - self._offset(sensor, rec[k, 3], rec[k, 4]), 0.0)
            count += hit
        rows = count > 0
        if rows.any():
            self._fit(sensor_id, xy[rows], raw[rows] - total[rows] / count[rows])
        old = self._recent.get(sensor_id, np.zeros((0, 5)))
        old = old[(t - old[:, 1] <= RECENT_S) & ~np.isin(old[:, 0], ids)]
        new = np.column_stack([ids, np.full(len(ids), t), raw, xy])
        both = np.concatenate([old, new])
        self._recent[sensor_id] = both[np.argsort(both[:, 0], kind="stable")]

    def _fit(self, sensor_id: str, xy: np.ndarray, residual: np.ndarray) -> None:
        ata, atb = self._normal.get(sensor_id, (np.zeros((3, 3)), np.zeros(3)))
        a = np.column_stack([np.ones(len(xy)), xy])
        fade = np.exp(-len(residual) / MEMORY)
        ata, atb = fade * ata + a.T @ a, fade * atb + a.T @ residual
        self._normal[sensor_id] = (ata, atb)
        if ata[0, 0] >= MIN_RESIDUALS:
            self._coef[sensor_id] = np.linalg.solve(ata + RIDGE * np.eye(3), atb)
            self._shared = self._mean_correction()

    def _mean_correction(self) -> float:
        """The corrections' mean over the (faded) detections they were learned from."""
        total = weight = 0.0
        for sensor, coef in self._coef.items():
            ata = self._normal[sensor][0]
            total += float(ata[0] @ coef)  # n times the mean of 1, x, y, dotted
            weight += float(ata[0, 0])
        return total / weight if weight > 0 else 0.0

    def _offset(self, sensor_id: str, x: Any, y: Any) -> Any:
        """What ``sensor_id`` adds to heights at ``(x, y)``, floats or arrays (0: unknown)."""
        coef = self._coef.get(sensor_id)
        if coef is None:
            return 0.0
        return coef[0] - self._shared + coef[1] * x + coef[2] * y

    def correct(self, sensor_id: str, xy: np.ndarray, height: np.ndarray) -> np.ndarray:
        """Heights ``(n,)`` measured by ``sensor_id`` at ``xy (n, 2)``, corrected."""
        if sensor_id not in self._coef or not len(height):
            return height
        return height - self._offset(sensor_id, xy[:, 0], xy[:, 1])

    def state(self) -> tuple[dict, dict, dict]:
        """For snapshots (copies)."""
        return (
            {k: (a.copy(), b.copy()) for k, (a, b) in self._normal.items()},
            {k: c.copy() for k, c in self._coef.items()},
            {k: r.copy() for k, r in self._recent.items()},
        )

    def restore(self, state: tuple) -> None:
        """Return to a :meth:`state` (one from before references were kept has none)."""
        normal, coef, *recent = state
        self._normal = {k: (a.copy(), b.copy()) for k, (a, b) in normal.items()}
        self._coef = {k: c.copy() for k, c in coef.items()}
        rows = recent[0] if recent else {}
        self._recent = {k: r.copy() for k, r in rows.items() if isinstance(r, np.ndarray)}
        self._shared = self._mean_correction()
