"""Where each sensor is known to see people: a map of floor cells per sensor.

A cell of a sensor is *covered* once the sensor has reported at least
:data:`COVERAGE_MIN_DETECTIONS` detections in it. The tracker asks which sensors should
see a track (its support) and how large the floor each sensor watches is (its clutter
density). With the map go the sensors' positions learned from the same detections
(:mod:`~openptrack_py.tracking.viewpoint`), which tell whether a covered track is hidden
behind another. Each batch is counted once, by its sequence number, in whatever order
batches are applied, so a late-batch replay has nothing to undo and the map is shared,
not copied, by snapshots.
"""

from __future__ import annotations

import numpy as np

from openptrack_py.tracking.lookup import find_sorted
from openptrack_py.tracking.viewpoint import Viewpoints, hidden

COVERAGE_CELL_M = 0.5
"""Side of a coverage cell, metres."""
COVERAGE_MIN_DETECTIONS = 5
"""Detections a sensor must have reported in a cell before it is known to see it."""
_REPLAYABLE_SEQS = 2048
"""Sequence numbers remembered per sensor (only the last moments can be replayed)."""


def _cell_codes(xy: np.ndarray) -> np.ndarray:
    """One integer per floor cell of the points ``xy (n, 2)``."""
    cells = np.floor(xy / COVERAGE_CELL_M).astype(np.int64)
    return (cells[:, 0] << 32) + (cells[:, 1] & 0xFFFFFFFF)


class _SensorCoverage:
    """One sensor's cell counts and its covered cells (as sorted codes, built lazily)."""

    def __init__(self) -> None:
        self.counts: dict[int, int] = {}
        self.covered: set[int] = set()
        self.seqs: set[int] = set()
        self._sorted: np.ndarray | None = np.zeros(0, dtype=np.int64)

    def add(self, codes: np.ndarray) -> None:
        for code in codes.tolist():
            n = self.counts.get(code, 0) + 1
            self.counts[code] = n
            if n == COVERAGE_MIN_DETECTIONS:
                self.covered.add(code)
                self._sorted = None

    def sorted_covered(self) -> np.ndarray:
        if self._sorted is None:
            self._sorted = np.array(sorted(self.covered), dtype=np.int64)
        return self._sorted


class Coverage:
    """The floor cells each sensor is known to see."""

    def __init__(self) -> None:
        self._sensors: dict[str, _SensorCoverage] = {}
        self._viewpoints = Viewpoints()

    def __setstate__(self, state: dict[str, object]) -> None:
        # a checkpoint written before the sensors' positions were learned
        self.__dict__.update(state)
        self.__dict__.setdefault("_viewpoints", Viewpoints())

    def mark(
        self, sensor_id: str, seq: int, xy: np.ndarray, distance: np.ndarray | None = None
    ) -> None:
        """Count a batch's detections ``xy`` in their cells, once per sequence number.

        Their ranges ``distance`` (if given) locate the sensor.
        """
        if not len(xy):
            return
        sensor = self._sensors.setdefault(sensor_id, _SensorCoverage())
        if seq >= 0:
            if seq in sensor.seqs:
                return  # a replay: counted already
            sensor.seqs.add(seq)
            if len(sensor.seqs) > 2 * _REPLAYABLE_SEQS:
                floor = max(sensor.seqs) - _REPLAYABLE_SEQS
                sensor.seqs.difference_update([q for q in sensor.seqs if q < floor])
        sensor.add(_cell_codes(xy))
        if distance is not None:
            self._viewpoints.add(sensor_id, xy, distance)

    def hidden(
        self, sensor_id: str, xy: np.ndarray, seen: np.ndarray, twin_m: float
    ) -> np.ndarray:
        """Mask of floor positions ``xy (n, 2)`` hidden from this sensor behind ``xy[seen]``.

        See :func:`~openptrack_py.tracking.viewpoint.hidden`; none while the sensor's
        position is not known.
        """
        view = self._viewpoints.view(sensor_id)
        if view is None:
            return np.zeros(len(xy), dtype=bool)
        return hidden(view[0], xy, seen, twin_m, view[1])

    def covers(self, sensor_id: str, xy: np.ndarray) -> np.ndarray:
        """Mask of floor positions ``xy (n, 2)`` in cells this sensor is known to see."""
        sensor = self._sensors.get(sensor_id)
        if sensor is None or not sensor.covered or not len(xy):
            return np.zeros(len(xy), dtype=bool)
        return find_sorted(sensor.sorted_covered(), _cell_codes(xy))[1]

    def covers_any(self, sensor_ids: list[str], xy: np.ndarray) -> np.ndarray:
        """Mask of floor positions ``xy (n, 2)`` that any of these sensors is known to see."""
        mask = np.zeros(len(xy), dtype=bool)
        known = [self._sensors[s] for s in sensor_ids if s in self._sensors]
        known = [s for s in known if s.covered]
        if known and len(xy):
            codes = _cell_codes(xy)
            for sensor in known:
                mask |= find_sorted(sensor.sorted_covered(), codes)[1]
        return mask

    def covered_cells(self, sensor_id: str) -> int:
        """How many cells this sensor is known to see."""
        sensor = self._sensors.get(sensor_id)
        return len(sensor.covered) if sensor is not None else 0

    def known(self, sensor_id: str) -> bool:
        """Whether this sensor has reported any detection."""
        return sensor_id in self._sensors
