"""Play a network's simulation in real time on a bus (the body of the ``sim`` node)."""

from __future__ import annotations

import functools
import time

from openptrack_py.calibration.files import network_calibration
from openptrack_py.config import NetworkConfig
from openptrack_py.errors import CalibrationError, ConfigError
from openptrack_py.messages.codec import encode_detection_batch, encode_ground_truth
from openptrack_py.runtime.node import Node
from openptrack_py.sim.scenarios import Scenario, build_scenario
from openptrack_py.sim.simulator import SensorFrame, Simulator


def scenario_from_network(cfg: NetworkConfig, *, calibrated: bool = True) -> Scenario:
    """The scenario a network file asks for, with its simulated sensors.

    The network's ``source: sim`` sensors replace the scenario's own placement unless
    ``sim.use_scenario_sensors`` is set or the network lists no simulated sensor; the
    sensors' noise profile is ``sim.profile``, with identity embeddings if
    ``sim.embeddings``.

    Sensors with a calibration entry (the network's ``calibration`` file or their own)
    report through the calibrated pose, not their simulated pose error; ``calibrated``
    off leaves the calibration out (rendering needs only the true poses).

    Raises
    ------
    ConfigError
        If the network has no ``sim`` section, or its calibration is unusable.
    """
    if cfg.sim is None:
        raise ConfigError("sim: the network file has no 'sim' section")
    try:
        calibration = network_calibration(cfg) if calibrated else None
    except CalibrationError as exc:
        raise ConfigError(str(exc)) from None
    simulated = [s for s in cfg.sensors if s.source == "sim"]
    sensors = None if cfg.sim.use_scenario_sensors or not simulated else simulated
    return build_scenario(
        cfg.sim.scenario,
        seed=cfg.sim.seed,
        duration_s=cfg.sim.duration_s,
        sensors=sensors,
        profile=cfg.sim.profile,
        embeddings=cfg.sim.embeddings,
        calibration=calibration,
    )


MAX_CAPTURE_LAG_S = 0.1
"""A frame captured this long ago (in played time) is skipped rather than simulated late."""


class LivePlayer:
    """Publishes a simulation's events at the times they happen.

    Each sensor batch goes to ``opt/<site>/detections/<sensor_id>`` when its simulated
    latency has elapsed; ground truth goes to ``opt/<site>/ground_truth``. If publishing
    falls behind the clock, events go out at once and are counted as ``late``; a sensor
    frame whose capture time is more than :data:`MAX_CAPTURE_LAG_S` behind the clock is
    dropped before it is simulated (``skipped``), as a real sensor's computer that cannot
    keep up drops frames, so that the simulator's own overload never shows downstream as
    stale data (latency) but as a lower frame rate.

    Parameters
    ----------
    scenario : Scenario
        What to play.
    node : Node
        The node whose bus, counters and stop flag to use.
    speed : float
        Playback speed relative to real time.
    ground_truth_rate_hz : float
        Rate of ground-truth messages.
    publish_detections : bool
        Publish the detection-level sensor batches; off when detector nodes render the
        sensors themselves (``sensor_model: rgbd``).
    start_time : float, optional
        UNIX time of the scenario's start (shared with rendering detectors); now if omitted.
    max_capture_lag_s : float or None
        Skip sensor frames captured longer ago than this (played time); ``None`` plays
        every frame however late (offline-identical output).
    """

    def __init__(
        self,
        scenario: Scenario,
        node: Node,
        *,
        speed: float = 1.0,
        ground_truth_rate_hz: float = 30.0,
        publish_detections: bool = True,
        start_time: float | None = None,
        max_capture_lag_s: float | None = MAX_CAPTURE_LAG_S,
    ) -> None:
        self.scenario = scenario
        self.max_capture_lag_s = max_capture_lag_s
        self.node = node
        self.speed = speed
        self.ground_truth_rate_hz = ground_truth_rate_hz
        self.publish_detections = publish_detections
        self.start_time = start_time
        keys = node.keys
        self._detections = (
            {s.id: node.publisher(keys.detections(s.id)) for s in scenario.sensors}
            if publish_detections
            else {}
        )
        self._truth = node.publisher(keys.ground_truth)

    def run(self) -> None:
        """Play until the scenario ends or the node is stopped."""
        start = self.start_time if self.start_time is not None else time.time() + 0.1
        sim = Simulator(
            self.scenario, start_time=start, ground_truth_rate_hz=self.ground_truth_rate_hz
        )
        counters = self.node.counters
        self.node.log.info(
            "playing scenario",
            extra={
                "fields": {
                    "scenario": self.scenario.name,
                    "seed": self.scenario.seed,
                    "sensors": ",".join(sim.sensor_ids),
                }
            },
        )

        def due(t: float) -> float:
            """Wall-clock time at which played time ``t`` happens."""
            return start + (t - start) / self.speed

        def behind(capture: float, limit: float) -> bool:
            lagging = time.time() - due(capture) > limit
            if lagging:
                counters.inc("skipped")
            return lagging

        limit = self.max_capture_lag_s
        guard = None if limit is None else functools.partial(behind, limit=limit)
        for event in sim.events(sensor_frames=self.publish_detections, skip_capture=guard):
            delay = due(event.time) - time.time()
            if delay > 0:
                if self.node.wait(delay):
                    break
            elif delay < -0.05:
                counters.inc("late")
            if not self.node.running:
                break
            if isinstance(event, SensorFrame):
                self._detections[event.batch.sensor_id].put(encode_detection_batch(event.batch))
                counters.inc("detections", len(event.batch.detections))
            else:
                self._truth.put(encode_ground_truth(event.frame))
