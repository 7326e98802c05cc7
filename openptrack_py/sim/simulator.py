"""Plays a scenario: world, sensors and ground truth as one time-ordered event stream.

:meth:`Simulator.events` yields :class:`SensorFrame` (a sensor's batch, at the true time
it would reach the network) and :class:`TruthFrame` (everyone's true state) in
non-decreasing time order. The same stream drives the real-time ``sim`` node, which
sleeps until each event's time, and offline evaluation, which does not sleep at all.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from openptrack_py.config import DetectorConfig
from openptrack_py.errors import ConfigError
from openptrack_py.messages.detection import DetectionBatch
from openptrack_py.messages.ground_truth import GroundTruthFrame, PersonState
from openptrack_py.sim.embeddings import IdentityVectors
from openptrack_py.sim.scenarios import Scenario, scenario_world
from openptrack_py.sim.sensors import Observation, SensorModel, SensorSpec
from openptrack_py.sim.world import Snapshot

DEFAULT_START_TIME = 1_767_225_600.0
"""2026-01-01T00:00:00Z: the clock of offline runs, so their stamps are reproducible."""


@dataclass(frozen=True, slots=True)
class SensorFrame:
    """One sensor batch as it reaches the network.

    Parameters
    ----------
    time : float
        True arrival time (capture time plus latency), UNIX seconds.
    capture_time : float
        True capture time, UNIX seconds. ``batch.stamp`` differs from it by the
        sensor's clock offset.
    batch : DetectionBatch
        What the sensor publishes.
    person_ids : tuple of int
        Ground-truth person behind each detection (0 for clutter and splits).
    """

    time: float
    capture_time: float
    batch: DetectionBatch
    person_ids: tuple[int, ...]


@dataclass(frozen=True, slots=True)
class TruthFrame:
    """Ground truth at one instant.

    Parameters
    ----------
    time : float
        True time, UNIX seconds.
    frame : GroundTruthFrame
        Everyone present.
    """

    time: float
    frame: GroundTruthFrame


Event = SensorFrame | TruthFrame

_APPEARANCE_KEY = 43
"""Seeds each sensor's appearance generator with the scenario seed and its index."""

_TRUTH = -1


class SimSensorModel(Protocol):
    """What the simulator needs of a sensor model: its sensor, its view, its detections."""

    spec: SensorSpec

    def covers(self, pos: np.ndarray, height: np.ndarray) -> np.ndarray:
        """Mask of people whose head is in view (occlusion ignored)."""

    def observe(self, snap: Snapshot) -> Observation:
        """What the sensor reports of a world snapshot."""


def _detection_models(
    scenario: Scenario, detector_config: DetectorConfig | None
) -> list[SimSensorModel]:
    """The detection-level model of every sensor (the default: fast).

    Each sensor has two generators: one for what it detects and where, one of its own
    for colour signatures and identity embeddings, so that these never move a
    detection. Identity vectors come from the scenario seed, shared by every sensor.
    """
    specs = scenario.sensors
    _, sensor_seq = np.random.SeedSequence(scenario.seed).spawn(2)
    identities = IdentityVectors(scenario.seed)
    return [
        SensorModel(
            spec,
            scenario.room,
            np.random.default_rng(seq),
            profile=scenario.profile,
            decoys=scenario.decoys,
            appearance_rng=np.random.default_rng([scenario.seed, _APPEARANCE_KEY, i]),
            identities=identities,
        )
        for i, (spec, seq) in enumerate(zip(specs, sensor_seq.spawn(len(specs)), strict=True))
    ]


def _rendered_models(
    scenario: Scenario, detector_config: DetectorConfig | None
) -> list[SimSensorModel]:
    """Rendered images through the real detector, per sensor (slow, detector in the loop)."""
    from openptrack_py.sim.rendered_model import RenderedSensorModel

    rngs = [np.random.default_rng([scenario.seed, 41, i]) for i in range(len(scenario.sensors))]
    return [
        RenderedSensorModel(spec, scenario.room, rng, detector_config)
        for spec, rng in zip(scenario.sensors, rngs, strict=True)
    ]


SENSOR_MODELS: dict[str, Callable[[Scenario, DetectorConfig | None], list[SimSensorModel]]] = {
    "detections": _detection_models,
    "rgbd": _rendered_models,
}
"""Sensor models by the name a network file or ``openptrack eval`` uses."""


class Simulator:
    """Runs a :class:`~openptrack_py.sim.scenarios.Scenario`.

    Parameters
    ----------
    scenario : Scenario
        What to simulate.
    start_time : float
        UNIX time of the scenario's start (wall clock for live runs).
    ground_truth_rate_hz : float or None
        Rate of :class:`TruthFrame` events; ``None`` for none.
    dt : float
        World step, seconds.
    sensor_model : {"detections", "rgbd"}
        ``detections``: the detection-level sensor model; ``rgbd``: render each sensor's
        images and run the real people detector on them (slower, detector in the loop).
    detector_config : DetectorConfig, optional
        Detector settings for ``rgbd``.
    """

    def __init__(
        self,
        scenario: Scenario,
        *,
        start_time: float = DEFAULT_START_TIME,
        ground_truth_rate_hz: float | None = 30.0,
        dt: float = 0.04,
        sensor_model: str = "detections",
        detector_config: DetectorConfig | None = None,
    ) -> None:
        self.scenario = scenario
        self.start_time = start_time
        self.ground_truth_rate_hz = ground_truth_rate_hz
        self.world = scenario_world(scenario, dt)
        if sensor_model not in SENSOR_MODELS:
            raise ConfigError(
                f"sensor_model: unknown {sensor_model!r} (allowed: {', '.join(SENSOR_MODELS)})"
            )
        self.models = SENSOR_MODELS[sensor_model](scenario, detector_config)
        self._frame_rngs = [
            np.random.default_rng([scenario.seed, 11, i]) for i in range(len(self.models))
        ]

    @property
    def sensor_ids(self) -> list[str]:
        """Ids of the simulated sensors."""
        return [m.spec.id for m in self.models]

    def covered(self, snap: Snapshot) -> np.ndarray:
        """Mask of people whose head is in view of at least one sensor."""
        mask = np.zeros(len(snap), dtype=bool)
        for model in self.models:
            mask |= model.covers(snap.pos, snap.height)
        return mask

    def truth(self, snap: Snapshot, seq: int) -> GroundTruthFrame:
        """Ground-truth message for a world snapshot."""
        covered = self.covered(snap)
        people = tuple(
            PersonState(
                id=int(snap.ids[i]),
                x=float(snap.pos[i, 0]),
                y=float(snap.pos[i, 1]),
                height=float(snap.height[i]),
                vx=float(snap.vel[i, 0]),
                vy=float(snap.vel[i, 1]),
                kind=str(snap.kinds[i]),
                covered=bool(covered[i]),
            )
            for i in range(len(snap))
        )
        return GroundTruthFrame(stamp=self.start_time + snap.t, seq=seq, people=people)

    def events(
        self,
        *,
        sensor_frames: bool = True,
        skip_capture: Callable[[float], bool] | None = None,
    ) -> Iterator[Event]:
        """Every event of the run, in non-decreasing ``time`` order.

        Parameters
        ----------
        sensor_frames : bool
            Off: only the ground truth; the sensors are not observed.
        skip_capture : callable, optional
            Called with each sensor frame's capture time (UNIX seconds) before it is
            observed; ``True`` drops the frame unobserved, as a sensor's computer that
            cannot keep up drops frames (the live player's real-time guard).
        """
        end = self.scenario.duration_s
        captures: list[tuple[float, int, int]] = []  # (scenario time, source, frame index)
        if sensor_frames:
            for i, model in enumerate(self.models):
                heapq.heappush(captures, (model.spec.phase_s, i, 0))
        if self.ground_truth_rate_hz:
            heapq.heappush(captures, (0.0, _TRUTH, 0))
        pending: list[tuple[float, int, int, SensorFrame]] = []
        # A sensor's pipeline publishes its frames in order: jitter never reorders them.
        last_arrival = [-float("inf")] * len(self.models)
        while captures:
            t, source, k = heapq.heappop(captures)
            if end is not None and t > end:
                continue
            while pending and pending[0][0] <= self.start_time + t:
                yield heapq.heappop(pending)[3]
            capture = self.start_time + t
            if source == _TRUTH:
                yield TruthFrame(capture, self.truth(self.world.state_at(t), k))
                heapq.heappush(captures, ((k + 1) / self.ground_truth_rate_hz, _TRUTH, k + 1))
                continue
            model = self.models[source]
            spec = model.spec
            heapq.heappush(captures, (spec.phase_s + (k + 1) / spec.rate_hz, source, k + 1))
            if skip_capture is not None and skip_capture(capture):
                continue  # skipped unobserved: not even the world's state is computed
            observation = model.observe(self.world.state_at(t))
            frame_rng = self._frame_rngs[source]
            latency = max(0.0, spec.latency_s + frame_rng.normal(0.0, spec.latency_jitter_s))
            if frame_rng.random() < spec.frame_drop_probability:
                continue  # lost frame: its seq number is never published
            arrival = max(capture + latency, last_arrival[source])
            last_arrival[source] = arrival
            batch = DetectionBatch(
                sensor_id=spec.id,
                seq=k,
                stamp=capture + spec.clock_offset_s - spec.clock_correction_s,
                frame_id="world",
                detections=observation.detections,
            )
            frame = SensorFrame(arrival, capture, batch, observation.person_ids)
            heapq.heappush(pending, (frame.time, source, k, frame))
        while pending:
            yield heapq.heappop(pending)[3]
