"""Which detection batches the tracker takes: admission control in front of the pipeline.

Bad *bytes* are refused by the decoder; admission refuses well-formed batches that would
still harm the tracker, each reason counted (the tracker node reports them in its stats):

* ``sensor_mismatch``: the batch's ``sensor_id`` differs from the key it came on;
* ``unknown_sensor``: a sensor the network file does not list (unless ``discover_sensors``
  is on; discovered sensors are forgotten once silent for ``sensor_forget_s``);
* ``wrong_frame``: a batch in another frame than the one configured;
* ``rate_limited``: more batches than twice the sensor's frame rate (a token bucket of one
  second's worth);
* ``bad_stamp``: a capture time that disagrees with the sensor's clock by more than
  ``max_clock_jump_s``. Each sensor's clock is the median of ``arrival - stamp`` over its
  recent admitted batches, so one batch stamped far in the future (or past) is refused
  and never moves that clock; a real step of the sensor's clock (NTP) is adopted once
  :data:`RESYNC_BATCHES` consecutive batches agree on it;
* ``detections_capped``: detections beyond what the sensor's view can hold (the most
  confident are kept, the rest counted).

A sensor's first batch has no clock yet: it is admitted when its stamp is within
``max_clock_offset_s`` of the arrival time.
"""

from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass, field, replace

from openptrack_py.messages.detection import DetectionBatch

CLOCK_SAMPLES = 31
"""Admitted batches whose ``arrival - stamp`` make a sensor's clock (their median)."""
RESYNC_BATCHES = 15
"""Consecutive refused batches that agree on a new clock before it is adopted."""

REASONS = (
    "sensor_mismatch",
    "unknown_sensor",
    "wrong_frame",
    "rate_limited",
    "bad_stamp",
    "detections_capped",
)
"""What admission counts (``detections_capped`` counts detections, the rest batches)."""


@dataclass(frozen=True)
class SensorLimits:
    """What one sensor may send.

    Parameters
    ----------
    rate_hz : float
        Its nominal frame rate; twice this is admitted.
    max_detections : int
        Most detections one of its batches may carry.
    """

    rate_hz: float
    max_detections: int


@dataclass
class _SensorState:
    limits: SensorLimits
    tokens: float
    token_time: float
    last_heard: float
    delays: deque[float] = field(default_factory=lambda: deque(maxlen=CLOCK_SAMPLES))
    refused: list[float] = field(default_factory=list)
    clock: float | None = None


def cap_detections(batch: DetectionBatch, cap: int) -> tuple[DetectionBatch, int]:
    """The batch with at most its ``cap`` most confident detections, and how many went."""
    excess = len(batch.detections) - cap
    if excess <= 0:
        return batch, 0
    keep = sorted(batch.detections, key=lambda d: -d.confidence)[:cap]
    return replace(batch, detections=tuple(keep)), excess


class Admission:
    """Admits or refuses each detection batch before it reaches the tracking pipeline.

    Parameters
    ----------
    sensors : mapping of str to SensorLimits
        The network's sensors.
    frame_id : str
        The frame tracked; batches in another are refused.
    discover_sensors : bool
        Admit sensors the network does not list (with ``default_limits``).
    default_limits : SensorLimits
        Limits of a discovered sensor.
    max_clock_offset_s : float
        A sensor's first batch is admitted only if stamped within this of its arrival.
    max_clock_jump_s : float
        Later batches must agree with the sensor's clock to within this.
    sensor_forget_s : float
        A discovered sensor silent this long is forgotten.
    """

    def __init__(
        self,
        sensors: dict[str, SensorLimits],
        frame_id: str = "world",
        *,
        discover_sensors: bool = False,
        default_limits: SensorLimits = SensorLimits(30.0, 50),
        max_clock_offset_s: float = 3600.0,
        max_clock_jump_s: float = 1.0,
        sensor_forget_s: float = 30.0,
    ) -> None:
        self.known = dict(sensors)
        self.frame_id = frame_id
        self.discover_sensors = discover_sensors
        self.default_limits = default_limits
        self.max_clock_offset_s = max_clock_offset_s
        self.max_clock_jump_s = max_clock_jump_s
        self.sensor_forget_s = sensor_forget_s
        self.counters: dict[str, int] = dict.fromkeys(REASONS, 0)
        self._sensors: dict[str, _SensorState] = {}
        self._last_prune = -float("inf")

    def admit(
        self, key_sensor: str | None, batch: DetectionBatch, arrival: float
    ) -> DetectionBatch | None:
        """The batch to track (capped), or ``None`` when refused (and counted).

        Parameters
        ----------
        key_sensor : str or None
            The sensor id of the key the batch came on (``None``: not checked).
        batch : DetectionBatch
            The batch as decoded.
        arrival : float
            Local arrival time, UNIX seconds.
        """
        self._prune(arrival)
        if key_sensor is not None and key_sensor != batch.sensor_id:
            return self._refuse("sensor_mismatch")
        state = self._state(batch.sensor_id, arrival)
        if state is None:
            return self._refuse("unknown_sensor")
        state.last_heard = max(state.last_heard, arrival)
        if batch.frame_id != self.frame_id:
            return self._refuse("wrong_frame")
        if not self._take_token(state, arrival):
            return self._refuse("rate_limited")
        if not self._plausible(state, arrival - batch.stamp):
            return self._refuse("bad_stamp")
        batch, excess = cap_detections(batch, state.limits.max_detections)
        self.counters["detections_capped"] += excess
        return batch

    def carry_over(self, previous: Admission) -> None:
        """Continue ``previous`` after a reconfiguration.

        Its counts carry over, and what it learned of each sensor's clock and rate when
        both track the same frame.
        """
        self.counters = previous.counters
        if previous.frame_id == self.frame_id:
            self._sensors = previous._sensors

    def sensors(self) -> list[str]:
        """The sensors heard from and not forgotten."""
        return sorted(self._sensors)

    def forget(self, sensor_id: str) -> None:
        """Drop what is known of a sensor's clock and rate."""
        self._sensors.pop(sensor_id, None)

    # ----------------------------------------------------------------- internals

    def _refuse(self, reason: str) -> None:
        self.counters[reason] += 1

    def _state(self, sensor_id: str, arrival: float) -> _SensorState | None:
        state = self._sensors.get(sensor_id)
        if state is not None:
            return state
        limits = self.known.get(sensor_id)
        if limits is None:
            if not self.discover_sensors:
                return None
            limits = self.default_limits
        rate = 2.0 * limits.rate_hz
        state = _SensorState(limits, tokens=rate, token_time=arrival, last_heard=arrival)
        self._sensors[sensor_id] = state
        return state

    @staticmethod
    def _take_token(state: _SensorState, arrival: float) -> bool:
        """Token bucket: twice the nominal rate, a second's worth of burst."""
        rate = 2.0 * state.limits.rate_hz
        elapsed = max(arrival - state.token_time, 0.0)
        state.tokens = min(rate, state.tokens + elapsed * rate)
        state.token_time = max(state.token_time, arrival)
        if state.tokens < 1.0:
            return False
        state.tokens -= 1.0
        return True

    def _plausible(self, state: _SensorState, delay: float) -> bool:
        """Whether ``arrival - stamp`` agrees with the sensor's clock (learning it)."""
        if state.clock is None:
            if abs(delay) > self.max_clock_offset_s:
                return False
        elif abs(delay - state.clock) > self.max_clock_jump_s:
            # refused, unless enough consecutive batches agree on a new clock
            state.refused.append(delay)
            recent = state.refused[-RESYNC_BATCHES:]
            if len(recent) < RESYNC_BATCHES or max(recent) - min(recent) > self.max_clock_jump_s:
                del state.refused[:-RESYNC_BATCHES]
                return False
            state.delays.clear()
            state.delays.extend(recent)
        state.refused.clear()
        state.delays.append(delay)
        state.clock = statistics.median(state.delays)
        return True

    def _prune(self, now: float) -> None:
        """Forget discovered sensors that fell silent (checked once a second)."""
        if now - self._last_prune < 1.0:
            return
        self._last_prune = now
        silent = [
            name
            for name, st in self._sensors.items()
            if name not in self.known and now - st.last_heard > self.sensor_forget_s
        ]
        for name in silent:
            del self._sensors[name]
