"""The tracker on a bus: detections in, tracks out, live reconfiguration.

:class:`TrackerService` is the body of the ``tracker`` node. It decodes every batch on
``opt/<site>/detections/*`` (malformed ones are counted and dropped by the node), runs
the :class:`~openptrack_py.tracking.pipeline.TrackingPipeline`, and publishes one
TrackBatch on ``opt/<site>/tracks`` after every step.

Admission control (:mod:`~openptrack_py.tracking.admission`) refuses, and counts, batches
that would harm the tracker although well formed: from a sensor the network does not
list, on another sensor's key, in another frame, faster than the sensor's rate, stamped
far from its clock; detections beyond what a sensor can see are capped. Load shedding: of
several batches of one sensor waiting together only the newest is tracked
(``superseded``), and a batch that waited longer than ``max_latency_s`` for the tracker
is dropped (``shed``); each step's tracks go out as soon as it is taken.

Live reconfiguration: a :class:`~openptrack_py.messages.ConfigUpdate` put on
``opt/<site>/config/<node>`` is validated against
:class:`~openptrack_py.config.TrackerConfig` and, if valid, applied between two steps
(tracks, ids and clock are kept). Every request is answered on
``opt/<site>/config/<node>/ack`` with whether it was applied, why not, and the
parameters in force. An invalid request changes nothing and never stops the node.
Nested parameters are set by dotted name (``identity.enabled=true``). Roster requests
(``openptrack roster``) come the same way (:mod:`~openptrack_py.tracking.roster_service`).
"""

from __future__ import annotations

import time

import orjson

from openptrack_py.config import NetworkConfig, TrackerConfig, apply_overrides, validate_config
from openptrack_py.errors import ConfigError
from openptrack_py.messages.codec import (
    decode_config_update,
    decode_detection_batch,
    encode_config_ack,
    encode_track_batch,
)
from openptrack_py.messages.config_update import ConfigAck, ConfigUpdate
from openptrack_py.messages.detection import DetectionBatch
from openptrack_py.runtime.counters import Counters
from openptrack_py.runtime.node import Inbox, Node, Received
from openptrack_py.sensor_types import SENSOR_TYPES
from openptrack_py.tracking.admission import Admission, SensorLimits, cap_detections
from openptrack_py.tracking.checkpoint import (
    Checkpoint,
    CheckpointStore,
    resume_ids,
    resume_tracks,
)
from openptrack_py.tracking.factory import build_tracker
from openptrack_py.tracking.ordering import ClockAligner
from openptrack_py.tracking.pipeline import TrackingPipeline
from openptrack_py.tracking.roster_service import ROSTER_KEY, RosterKeeper

RESUME_MARGIN_S = 0.1
"""Resumed tracks are as of this long before the first batch after a restart (its stamp
may still be shifted back a little by the clock alignment)."""
INBOX_BATCHES = 256
"""Batches waiting for the tracker at most (load shedding drops the stale ones anyway)."""
FIXED_WHILE_RUNNING = frozenset({"host", "state_dir"})
"""Parameters that only take effect at start-up."""


def tracked_frame(network: NetworkConfig, config: TrackerConfig) -> str:
    """The frame the tracker fuses.

    The configured one, else ``world``, unless the network is one sensor without a pose
    (then that sensor's own floor frame, named by its id).
    """
    if config.frame_id is not None:
        return config.frame_id
    sensors = network.sensors
    if len(sensors) == 1 and sensors[0].pose is None and sensors[0].calibration is None:
        return sensors[0].id
    return "world"


def build_admission(network: NetworkConfig, config: TrackerConfig) -> Admission:
    """Admission control for the network's sensors under the tracker's settings."""
    limits = {}
    for sensor in network.sensors:
        kind = SENSOR_TYPES[sensor.type]
        limits[sensor.id] = SensorLimits(sensor.rate_hz or kind.rate_hz, kind.max_people_in_view)
    widest = max(SENSOR_TYPES.values(), key=lambda k: k.max_people_in_view)
    return Admission(
        limits,
        tracked_frame(network, config),
        discover_sensors=config.discover_sensors or not network.sensors,
        default_limits=SensorLimits(
            max(k.rate_hz for k in SENSOR_TYPES.values()), widest.max_people_in_view
        ),
        max_clock_offset_s=config.max_clock_offset_s,
        max_clock_jump_s=config.max_clock_jump_s,
        sensor_forget_s=config.sensor_forget_s,
    )


def newest_per_sensor(
    admitted: list[tuple[DetectionBatch, float]], counters: Counters
) -> list[tuple[DetectionBatch, float]]:
    """Of each sensor's batches (with arrival times), the newest; the rest ``superseded``."""
    newest = {batch.sensor_id: i for i, (batch, _) in enumerate(admitted)}
    if len(newest) == len(admitted):
        return admitted
    counters.inc("superseded", len(admitted) - len(newest))
    return [pair for i, pair in enumerate(admitted) if newest[pair[0].sensor_id] == i]


class TrackerService:
    """Runs a tracker on a node.

    Parameters
    ----------
    node : Node
        The node (bus, counters, stop flag).
    config : TrackerConfig
        Initial parameters.
    network : NetworkConfig, optional
        The network: its sensors are the ones admitted (a network that lists none
        admits every sensor, as ``discover_sensors`` does).
    idle_s : float
        Longest wait for a batch before checking the reorder buffer's timeouts.
    """

    def __init__(
        self,
        node: Node,
        config: TrackerConfig,
        network: NetworkConfig | None = None,
        idle_s: float = 0.005,
    ) -> None:
        self.node = node
        self.config = config
        self.network = network if network is not None else NetworkConfig()
        self.idle_s = idle_s
        self.pipeline = TrackingPipeline.from_config(config)
        self.admission = build_admission(self.network, config)
        self.pipeline.tracker.frame_id = self.admission.frame_id
        keys = node.keys
        self._key_prefix = keys.detections("")
        # the most any sensor may send: detections beyond it are dropped as they arrive,
        # so a flood of huge batches never fills memory while they wait
        self._max_detections = max(
            [lim.max_detections for lim in self.admission.known.values()]
            + [self.admission.default_limits.max_detections]
        )
        self._batches = node.subscribe(
            keys.detections("*"), self._decode_capped, maxsize=INBOX_BATCHES
        )
        self._updates: Inbox[Received[ConfigUpdate]] = node.subscribe(
            keys.config(node.name), decode_config_update, maxsize=100
        )
        self._store: CheckpointStore | None = None
        self._pending: Checkpoint | None = None
        self._saved_at = time.monotonic()
        if config.state_dir is not None:
            self._store = CheckpointStore(config.state_dir / f"tracker-{node.keys.site}.ckpt")
            self._resume()
        self._tracks = node.publisher(keys.tracks)
        self._acks = node.publisher(keys.config_ack(node.name))
        self._reported: dict[str, int] = {}
        self._roster = RosterKeeper(config.identity.roster_file)

    # ----------------------------------------------------------------- checkpoints

    def _resume(self) -> None:
        """Continue the ids of the checkpoint on disk; its tracks at the first batch."""
        assert self._store is not None
        ckpt = self._store.load()
        if ckpt is None:
            return
        tracker = self.pipeline.tracker
        resume_ids(tracker, ckpt)
        age = time.time() - ckpt.saved_at
        if 0 <= age <= self.config.resume_within_s and ckpt.frame_id == self.admission.frame_id:
            self._pending = ckpt
        tracks = len(ckpt.table) if self._pending else 0
        self.node.log.info(
            "resuming from checkpoint",
            extra={"fields": {"tracks": tracks, "next_id": tracker.max_id + 1}},
        )

    def _resume_tracks(self, batch: DetectionBatch) -> None:
        """At the first batch after a restart: the checkpoint's tracks, as of just before it."""
        ckpt, self._pending = self._pending, None
        if ckpt is not None:
            resume_tracks(self.pipeline.tracker, ckpt, batch.stamp - RESUME_MARGIN_S)

    def _checkpoint(self, force: bool = False) -> None:
        """Write the checkpoint when due (every interval, or before ids run past it)."""
        if self._store is None:
            return
        now = time.monotonic()
        tracker = self.pipeline.tracker
        due = now - self._saved_at >= self.config.checkpoint_interval_s
        if force or due or self._store.due(tracker):
            try:
                self._store.save(tracker)
            except OSError as exc:
                self.node.counters.inc("checkpoint_errors")
                self.node.bad_input.warning("checkpoint", f"cannot write checkpoint: {exc}")
            self._saved_at = now

    def _decode_capped(self, payload: bytes) -> DetectionBatch:
        """Decode a batch, keeping at most the most confident detections any sensor may send."""
        batch, excess = cap_detections(decode_detection_batch(payload), self._max_detections)
        if excess:
            self.node.counters.inc("detections_capped", excess)
        return batch

    # ------------------------------------------------------------- reconfiguration

    def apply(self, update: ConfigUpdate) -> ConfigAck:
        """Validate and apply an update; return the acknowledgement to send."""
        if ROSTER_KEY in update.set:
            return self._roster_request(update)
        fixed = sorted(FIXED_WHILE_RUNNING & set(update.set))
        try:
            if fixed:
                raise ConfigError(f"{', '.join(fixed)}: cannot be changed while running")
            merged = apply_overrides(
                self.config.model_dump(),
                [f"{k}={orjson.dumps(v).decode()}" for k, v in update.set.items()],
            )
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

    def _roster_request(self, update: ConfigUpdate) -> ConfigAck:
        """Apply a roster request (``openptrack roster``) and answer it."""
        try:
            listing = self._roster.request(self.pipeline.tracker.identity, update.set)
        except ConfigError as exc:
            self.node.counters.inc("roster_rejected")
            return ConfigAck(update.id, self.node.name, False, str(exc), {})
        self.node.log.info("roster request", extra={"fields": {"id": update.id}})
        return ConfigAck(update.id, self.node.name, True, "", listing)

    def _dump(self) -> dict:
        return self.config.model_dump(mode="json")

    def _reconfigure(self, new: TrackerConfig) -> None:
        tracker = build_tracker(new)
        tracker.adopt_state(self.pipeline.tracker)
        self.pipeline.tracker = tracker
        self.pipeline.buffer.window_s = new.reorder_window_s
        if new.clock_correction != self.config.clock_correction:
            self.pipeline.aligner = ClockAligner() if new.clock_correction == "arrival" else None
        fresh = build_admission(self.network, new)
        fresh.carry_over(self.admission)
        self.admission = fresh
        tracker.frame_id = fresh.frame_id
        self.config = new
        self._roster = RosterKeeper(new.identity.roster_file)

    # ---------------------------------------------------------------------- loop

    def _publish(self, results: list) -> int:
        """Publish every step's tracks; return the number of steps."""
        now = time.time()
        for batch, tracks in results:
            self._tracks.put(encode_track_batch(tracks))
            self.node.counters.add_timing("capture_to_publish", now - batch.stamp)
        return len(results)

    def _report_counters(self) -> None:
        counters = self.node.counters
        counts = {**self.pipeline.tracker.counters, **self.admission.counters}
        for name, value in counts.items():
            delta = value - self._reported.get(name, 0)
            if delta > 0:
                counters.inc(name, delta)
            self._reported[name] = value

    def _admit(self, item: Received[DetectionBatch], now: float) -> DetectionBatch | None:
        """The batch to track, or ``None`` if shed or refused (counted either way)."""
        if now - item.received > self.config.max_latency_s:
            self.node.counters.inc("shed")
            return None
        key_sensor = item.key[len(self._key_prefix) :] if item.key else None
        batch = self.admission.admit(key_sensor, item.message, item.received)
        if batch is None:
            sensor = item.message.sensor_id
            self.node.bad_input.warning(
                f"refused:{sensor}", "batch refused by admission control", sensor=sensor
            )
        return batch

    def step_once(self, timeout_s: float | None = None) -> int:
        """Handle pending updates, then pending batches; return the number of steps.

        Each step's tracks are published as soon as it is taken. Of several admitted
        batches of one sensor waiting together, only the newest is tracked (the others
        are counted as ``superseded``): a tracker that fell a frame behind catches up at
        once instead of carrying the delay, as a detector keeps only its newest frame.
        """
        for item in self._updates.drain(timeout=0):
            self._acks.put(encode_config_ack(self.apply(item.message)))
        counters = self.node.counters
        steps = 0
        with counters.timed("step"):
            admitted = []
            for item in self._batches.drain(timeout=timeout_s):
                now = time.time()
                counters.add_timing("inbox", now - item.received)
                batch = self._admit(item, now)
                if batch is not None:
                    admitted.append((batch, item.received))
            for batch, received in newest_per_sensor(admitted, counters):
                if self._pending is not None:
                    self._resume_tracks(batch)
                steps += self._publish(self.pipeline.push(batch, received))
            steps += self._publish(self.pipeline.poll(time.time()))
        self._report_counters()
        self._checkpoint()
        problem = self._roster.reload_if_changed(self.pipeline.tracker.identity)
        if problem:
            self.node.counters.inc("roster_errors")
            self.node.bad_input.warning("roster", f"roster file not loaded: {problem}")
        return steps

    def run(self) -> None:
        """Track until the node stops."""
        self.node.log.info("tracking", extra={"fields": {"keys": self.node.keys.detections("*")}})
        while self.node.running:
            self.step_once(timeout_s=self.idle_s)
        self._publish(self.pipeline.flush())
        self._checkpoint(force=True)
