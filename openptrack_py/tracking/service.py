"""The tracker on a bus: detections in, tracks out, live reconfiguration.

:class:`TrackerService` is the body of the ``tracker`` node. It decodes every batch on
``opt/<site>/detections/*`` (malformed ones are counted and dropped by the node), runs
the :class:`~openptrack_py.tracking.pipeline.TrackingPipeline`, and publishes one
TrackBatch on ``opt/<site>/tracks`` after every step.

Live reconfiguration: a :class:`~openptrack_py.messages.ConfigUpdate` put on
``opt/<site>/config/<node>`` is validated against
:class:`~openptrack_py.config.TrackerConfig` and, if valid, applied between two steps
(tracks, ids and clock are kept). Every request is answered on
``opt/<site>/config/<node>/ack`` with whether it was applied, why not, and the
parameters in force. An invalid request changes nothing and never stops the node.
"""

from __future__ import annotations

import time

from openptrack_py.config import TrackerConfig, validate_config
from openptrack_py.errors import ConfigError
from openptrack_py.messages.codec import (
    decode_config_update,
    decode_detection_batch,
    encode_config_ack,
    encode_track_batch,
)
from openptrack_py.messages.config_update import ConfigAck, ConfigUpdate
from openptrack_py.messages.detection import DetectionBatch
from openptrack_py.runtime.node import Inbox, Node, Received
from openptrack_py.tracking.factory import build_tracker
from openptrack_py.tracking.ordering import ClockAligner
from openptrack_py.tracking.pipeline import TrackingPipeline

FIXED_WHILE_RUNNING = frozenset({"host"})
"""Parameters that only take effect at start-up."""


class TrackerService:
    """Runs a tracker on a node.

    Parameters
    ----------
    node : Node
        The node (bus, counters, stop flag).
    config : TrackerConfig
        Initial parameters.
    idle_s : float
        Longest wait for a batch before checking the reorder buffer's timeouts.
    """

    def __init__(self, node: Node, config: TrackerConfig, idle_s: float = 0.005) -> None:
        self.node = node
        self.config = config
        self.idle_s = idle_s
        self.pipeline = TrackingPipeline.from_config(config)
        keys = node.keys
        self._frame: str | None = None
        self._batches = node.subscribe(keys.detections("*"), decode_detection_batch, maxsize=1000)
        self._updates: Inbox[Received[ConfigUpdate]] = node.subscribe(
            keys.config(node.name), decode_config_update, maxsize=100
        )
        self._tracks = node.publisher(keys.tracks)
        self._acks = node.publisher(keys.config_ack(node.name))
        self._reported: dict[str, int] = {}

    # ------------------------------------------------------------- reconfiguration

    def apply(self, update: ConfigUpdate) -> ConfigAck:
        """Validate and apply an update; return the acknowledgement to send."""
        fixed = sorted(FIXED_WHILE_RUNNING & set(update.set))
        try:
            if fixed:
                raise ConfigError(f"{', '.join(fixed)}: cannot be changed while running")
            merged = {**self.config.model_dump(), **update.set}
            new = validate_config(TrackerConfig, merged, f"config/{self.node.name}")
        except ConfigError as exc:
            self.node.counters.inc("config_rejected")
            self.node.log.warning(
                "configuration update refused",
                extra={"fields": {"id": update.id, "error": str(exc)}},
            )
            return ConfigAck(update.id, self.node.name, False, str(exc), self._dump())
        if update.set:
            self._reconfigure(new)
            self.node.counters.inc("config_applied")
            self.node.log.info(
                "configuration updated", extra={"fields": {"id": update.id, **update.set}}
            )
        return ConfigAck(update.id, self.node.name, True, "", self._dump())

    def _dump(self) -> dict:
        return self.config.model_dump(mode="json")

    def _reconfigure(self, new: TrackerConfig) -> None:
        tracker = build_tracker(new)
        tracker.adopt_state(self.pipeline.tracker)
        self.pipeline.tracker = tracker
        self.pipeline.buffer.window_s = new.reorder_window_s
        if new.clock_correction != self.config.clock_correction:
            self.pipeline.aligner = ClockAligner() if new.clock_correction == "arrival" else None
        self.config = new

    # ---------------------------------------------------------------------- loop

    def _publish(self, results: list) -> None:
        for _batch, tracks in results:
            self._tracks.put(encode_track_batch(tracks))

    def _report_counters(self) -> None:
        counters = self.node.counters
        for name, value in self.pipeline.tracker.counters.items():
            delta = value - self._reported.get(name, 0)
            if delta > 0:
                counters.inc(name, delta)
            self._reported[name] = value

    def _in_frame(self, batch: DetectionBatch) -> bool:
        """Whether a batch is in the frame being tracked (the first batch's frame).

        Sensors with a pose report in ``world``; one without reports in its own floor
        frame, which can be tracked alone but never fused with others: such batches are
        counted as ``wrong_frame`` and dropped.
        """
        tracker = self.pipeline.tracker
        if self._frame is None:
            self._frame = tracker.frame_id = batch.frame_id
        if batch.frame_id == self._frame:
            return True
        self.node.counters.inc("wrong_frame")
        self.node.bad_input.warning(
            f"frame:{batch.sensor_id}",
            "batch in another frame than the one tracked: dropped",
            sensor=batch.sensor_id,
            frame=batch.frame_id,
            tracked=self._frame,
        )
        return False

    def step_once(self, timeout_s: float | None = None) -> int:
        """Handle pending updates, then pending batches; return the number of steps."""
        for item in self._updates.drain(timeout=0):
            self._acks.put(encode_config_ack(self.apply(item.message)))
        results = []
        with self.node.counters.timed("step"):
            for item in self._batches.drain(timeout=timeout_s):
                if self._in_frame(item.message):
                    results += self.pipeline.push(item.message, item.received)
            results += self.pipeline.poll(time.time())
        self._publish(results)
        self._report_counters()
        return len(results)

    def run(self) -> None:
        """Track until the node stops."""
        self.node.log.info("tracking", extra={"fields": {"keys": self.node.keys.detections("*")}})
        while self.node.running:
            self.step_once(timeout_s=self.idle_s)
        self._publish(self.pipeline.flush())
