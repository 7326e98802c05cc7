"""The oracle: a hypothesis feed that reports the ground truth itself.

It must score perfectly, which proves the harness; its injected faults (a relabel, a
swap, a dropout) must cost exactly what they should.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from openptrack_py.eval.runner import Hypotheses
from openptrack_py.messages.ground_truth import GroundTruthFrame
from openptrack_py.sim.simulator import SensorFrame, TruthFrame


@dataclass
class TruthFeed:
    """Reports the ground truth itself, optionally with injected faults.

    Parameters
    ----------
    relabel : tuple of (int, float), optional
        ``(person_id, from_time_s)``: that person's id changes from then on (one
        identity switch).
    swap : tuple of (int, int, float), optional
        ``(person_a, person_b, from_time_s)``: two people exchange ids (two switches).
    drop : tuple of (float, float), optional
        ``(start_s, end_s)``: no output at all in that window (every object a miss).
    start_time : float
        Scenario start (UNIX), to which the fault times are relative.
    """

    relabel: tuple[int, float] | None = None
    swap: tuple[int, int, float] | None = None
    drop: tuple[float, float] | None = None
    start_time: float = 0.0
    _truth: GroundTruthFrame | None = None

    def on_sensor_frame(self, frame: SensorFrame) -> None:
        """The oracle ignores sensors."""

    def on_truth_frame(self, frame: TruthFrame) -> None:
        """Remember the latest truth."""
        self._truth = frame.frame

    def hypotheses_at(self, t: float) -> Hypotheses | None:
        """The truth at ``t`` with the configured faults."""
        rel = t - self.start_time
        if self._truth is None or (self.drop and self.drop[0] <= rel < self.drop[1]):
            return None
        ids = []
        for p in self._truth.people:
            pid = p.id
            if self.relabel and pid == self.relabel[0] and rel >= self.relabel[1]:
                pid = 1_000_000 + pid
            if self.swap and rel >= self.swap[2]:
                a, b = self.swap[0], self.swap[1]
                pid = b if pid == a else a if pid == b else pid
            ids.append(pid)
        xy = np.array([(p.x, p.y) for p in self._truth.people]).reshape(-1, 2)
        return Hypotheses(np.array(ids, dtype=np.int64), xy)
