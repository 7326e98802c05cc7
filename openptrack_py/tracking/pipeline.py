"""The tracker behind its clock alignment and reorder window: what a node or an evaluation runs.

Batches go in as they arrive (with their arrival time); each is shifted by its sensor's
clock correction, held in the reorder window until it can go in capture order, and then
applied by the tracker. Every step's ``(batch, tracks)`` comes out.
"""

from __future__ import annotations

from dataclasses import replace

from openptrack_py.config import TrackerConfig
from openptrack_py.messages.detection import DetectionBatch
from openptrack_py.messages.track import TrackBatch
from openptrack_py.tracking.factory import build_tracker
from openptrack_py.tracking.ordering import ClockAligner, ReorderBuffer
from openptrack_py.tracking.tracker import Tracker


class TrackingPipeline:
    """Clock alignment, reordering and the tracker, for a node or an evaluation.

    Parameters
    ----------
    tracker : Tracker
        The tracker.
    window_s : float
        Reorder window.
    clock_correction : {"arrival", "none"}
        Whether to align sensor clocks.
    """

    def __init__(
        self, tracker: Tracker, window_s: float = 0.05, clock_correction: str = "arrival"
    ) -> None:
        self.tracker = tracker
        self.buffer = ReorderBuffer(window_s)
        self.aligner = ClockAligner() if clock_correction == "arrival" else None

    @classmethod
    def from_config(cls, config: TrackerConfig) -> TrackingPipeline:
        """The tracker of ``config`` behind its reorder window and clock correction."""
        return cls(build_tracker(config), config.reorder_window_s, config.clock_correction)

    @property
    def late(self) -> int:
        """Batches captured before one already applied (replayed or dropped)."""
        counters = self.tracker.counters
        return counters["late_applied"] + counters["late_dropped"]

    def push(
        self, batch: DetectionBatch, arrival: float
    ) -> list[tuple[DetectionBatch, TrackBatch]]:
        """Take a batch as it arrives; return ``(batch, tracks)`` for every step taken.

        The returned batches carry the corrected stamps the tracker used.
        """
        if self.aligner is not None:
            self.aligner.observe(batch.sensor_id, batch.stamp, arrival)
            shift = self.aligner.correction(batch.sensor_id)
            if shift:
                batch = replace(batch, stamp=batch.stamp + shift)
        return self._run(self.buffer.push(batch, arrival))

    def poll(self, now: float) -> list[tuple[DetectionBatch, TrackBatch]]:
        """Step with batches whose wait is over (call regularly when idle)."""
        return self._run(self.buffer.release(now))

    def flush(self) -> list[tuple[DetectionBatch, TrackBatch]]:
        """Step with everything still held."""
        return self._run(self.buffer.flush())

    def _run(self, batches: list[DetectionBatch]) -> list[tuple[DetectionBatch, TrackBatch]]:
        return [(batch, self.tracker.step(batch)) for batch in batches]
