"""The sensors as configured: nothing learned (the sensor role without learning).

:class:`~openptrack_py.tracking.sensor_model.OnlineSensorModel` learns each sensor's
noise, alignment, clutter and coverage; :class:`StaticSensorModel` trusts the
configuration, for tests and for comparing what the learning buys.
"""

from __future__ import annotations

import numpy as np

from openptrack_py.tracking.sensor_model import SensorUpdates
from openptrack_py.tracking.state import DetectionArrays, TrackTable


class StaticSensorModel:
    """Every sensor exactly as configured: no noise scale, no bias, no coverage."""

    def noise_scale(self, sensor_id: str, distance: np.ndarray) -> np.ndarray:
        """Always 1."""
        return np.ones(len(distance))

    def correct(self, dets: DetectionArrays) -> DetectionArrays:
        """The detections unchanged."""
        return dets

    def cross_sensor_var(
        self, sensor_id: str, distance: np.ndarray, last_sensor: np.ndarray, names: list[str]
    ) -> None:
        """Calibrations are trusted: nothing added."""
        return None

    def clutter_density(self, sensor_id: str) -> float:
        """None known: never stops an association."""
        return 0.0

    def observe_frame(self, sensor_id: str, unexplained: int) -> None:
        """Nothing to learn."""

    def covers(self, sensor_id: str, xy: np.ndarray) -> np.ndarray:
        """No coverage is known."""
        return np.zeros(len(xy), dtype=bool)

    def hidden(
        self, sensor_id: str, xy: np.ndarray, seen: np.ndarray, twin_m: float
    ) -> np.ndarray:
        """Nothing is known to be hidden."""
        return np.zeros(len(xy), dtype=bool)

    def learn(self, updates: SensorUpdates) -> None:
        """Nothing to learn."""

    def observe_tracks(self, table: TrackTable, t: float, names: list[str]) -> None:
        """Nothing to learn."""
