"""Putting several sensors' batches in capture order: clock alignment and a reorder window.

Batches from several sensors reach the tracker in arrival order, which is not capture
order (latencies differ and jitter), and each sensor stamps them with its own clock.
Before the tracker sees them (:class:`~openptrack_py.tracking.pipeline.TrackingPipeline`):

* :class:`ClockAligner` (``clock_correction: arrival``) estimates each sensor's
  ``arrival - stamp`` as its running minimum over the last minute (jitter only ever adds
  delay, so the minimum is the offset plus the smallest latency) and shifts every
  sensor's stamps so that all agree with the median sensor. A sensor whose clock is off
  by a constant is therefore aligned within its first frames; what remains is the
  difference between the sensors' smallest latencies (a few milliseconds on a LAN).
* :class:`ReorderBuffer` holds a batch until either every other live sensor has
  delivered a frame that must be later than it (known from each sensor's frame
  period), or it has waited ``window_s``. In steady state this adds almost no delay.
* A batch captured before one already applied is *late*; the tracker replays it from
  its state before that capture (:mod:`openptrack_py.tracking.replay`), or drops it
  (``late_policy``), and it is counted.
"""

from __future__ import annotations

import bisect
import statistics
from collections import deque
from dataclasses import dataclass, field

from openptrack_py.messages.detection import DetectionBatch


@dataclass
class _SensorClock:
    samples: deque[tuple[float, float]] = field(default_factory=deque)  # (arrival, delay)
    offset: float = 0.0


class ClockAligner:
    """Aligns sensors whose clocks disagree by a constant.

    Parameters
    ----------
    memory_s : float
        How long a delay sample counts towards a sensor's minimum.
    """

    def __init__(self, memory_s: float = 60.0) -> None:
        self.memory_s = memory_s
        self._sensors: dict[str, _SensorClock] = {}
        self._last_prune = -float("inf")

    def observe(self, sensor_id: str, stamp: float, arrival: float) -> None:
        """Record one batch's arrival."""
        clock = self._sensors.setdefault(sensor_id, _SensorClock())
        samples = clock.samples
        delay = arrival - stamp
        # monotone deque: keeps candidates for the sliding-window minimum
        while samples and samples[-1][1] >= delay:
            samples.pop()
        samples.append((arrival, delay))
        while samples[0][0] < arrival - self.memory_s:
            samples.popleft()
        clock.offset = samples[0][1]
        if len(self._sensors) > 1 and arrival - self._last_prune > 1.0:
            self._last_prune = arrival
            for name in [
                n for n, c in self._sensors.items() if c.samples[-1][0] < arrival - self.memory_s
            ]:
                del self._sensors[name]  # silent for the whole memory: forgotten

    def correction(self, sensor_id: str) -> float:
        """Seconds to add to this sensor's stamps."""
        if sensor_id not in self._sensors:
            return 0.0
        reference = statistics.median(c.offset for c in self._sensors.values())
        return self._sensors[sensor_id].offset - reference

    def corrections(self) -> dict[str, float]:
        """Current correction of every known sensor."""
        return {s: self.correction(s) for s in self._sensors}


@dataclass
class _SensorTiming:
    last_stamp: float
    last_arrival: float
    period: float | None = None


class ReorderBuffer:
    """Releases batches in capture order, waiting at most ``window_s`` for stragglers.

    Parameters
    ----------
    window_s : float
        Longest wait of a batch; 0 releases everything at once (arrival order).
    sensor_timeout_s : float
        A sensor silent this long is not waited for (and after ten times as long it is
        forgotten).
    """

    def __init__(self, window_s: float = 0.05, sensor_timeout_s: float = 1.0) -> None:
        if window_s < 0:
            raise ValueError(f"ReorderBuffer: window_s must be >= 0, got {window_s}")
        self.window_s = window_s
        self.sensor_timeout_s = sensor_timeout_s
        self._held: list[tuple[float, int, float, DetectionBatch]] = []  # stamp, n, arrival
        self._count = 0
        self._sensors: dict[str, _SensorTiming] = {}
        self._last_prune = -float("inf")

    def __len__(self) -> int:
        return len(self._held)

    def push(self, batch: DetectionBatch, arrival: float) -> list[DetectionBatch]:
        """Add a batch (stamp already clock-corrected); return what can go now."""
        timing = self._sensors.get(batch.sensor_id)
        if timing is None:
            self._sensors[batch.sensor_id] = _SensorTiming(batch.stamp, arrival)
        else:
            gap = batch.stamp - timing.last_stamp
            if gap > 0:
                timing.period = (
                    gap if timing.period is None else min(0.9 * timing.period + 0.1 * gap, gap * 4)
                )
            timing.last_stamp = max(timing.last_stamp, batch.stamp)
            timing.last_arrival = arrival
        self._count += 1
        bisect.insort(self._held, (batch.stamp, self._count, arrival, batch))
        if arrival - self._last_prune > self.sensor_timeout_s:
            self._last_prune = arrival
            forget = 10.0 * self.sensor_timeout_s
            for name in [n for n, s in self._sensors.items() if arrival - s.last_arrival > forget]:
                del self._sensors[name]
        return self.release(arrival)

    def _safe(self, stamp: float, sensor_id: str, now: float) -> bool:
        """Whether no live sensor can still deliver a batch captured before ``stamp``."""
        for name, timing in self._sensors.items():
            if name == sensor_id or now - timing.last_arrival > self.sensor_timeout_s:
                continue
            if timing.last_stamp >= stamp:
                continue
            if timing.period is None or timing.last_stamp + 0.8 * timing.period < stamp:
                return False
        return True

    def release(self, now: float) -> list[DetectionBatch]:
        """Batches that need wait no longer, oldest capture first."""
        out = []
        while self._held:
            stamp, _, arrival, batch = self._held[0]
            if now - arrival >= self.window_s or self._safe(stamp, batch.sensor_id, now):
                out.append(self._held.pop(0)[3])
            else:
                break
        return out

    def flush(self) -> list[DetectionBatch]:
        """Everything still held, oldest first."""
        out = [item[3] for item in self._held]
        self._held.clear()
        return out
