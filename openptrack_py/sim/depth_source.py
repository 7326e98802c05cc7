"""A rendered simulated sensor as a depth source (``sensor_model: rgbd``).

:class:`SimDepthSource` plays a scenario's world and renders one sensor's view at that
sensor's rate. Every process that simulates part of a scenario builds the same world
from the same seed, so a detector node rendering its sensor and the ``sim`` node
publishing ground truth agree on where everybody is, given a shared ``start_time``.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator

import numpy as np

from openptrack_py.config import DetectorConfig
from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.detection.pipeline import PeopleDetector
from openptrack_py.errors import ConfigError
from openptrack_py.geometry import world_from_optical
from openptrack_py.sim.render import DepthRenderer
from openptrack_py.sim.scenarios import Scenario
from openptrack_py.sim.sensors import Observation, SensorModel, SensorSpec
from openptrack_py.sim.simulator import scenario_world
from openptrack_py.sim.world import Room, Snapshot


class SimDepthSource:
    """Renders one simulated sensor's frames, in real time or as fast as possible.

    Parameters
    ----------
    scenario : Scenario
        The scenario (its sensors must include ``sensor_id``).
    sensor_id : str
        Which sensor to render.
    start_time : float
        UNIX time of the scenario's start.
    speed : float
        Playback speed relative to real time.
    rate_hz : float, optional
        Frame rate (the sensor's own if omitted).
    realtime : bool
        Pace frames by the clock, skipping frames that are already past when behind
        (a live sensor does not wait for its consumer); otherwise render every frame at
        once.
    clock : callable
        Time source, for tests.

    Raises
    ------
    ConfigError
        If the scenario has no such sensor.
    """

    def __init__(
        self,
        scenario: Scenario,
        sensor_id: str,
        *,
        start_time: float,
        speed: float = 1.0,
        rate_hz: float | None = None,
        realtime: bool = True,
        clock: Callable[[], float] = time.time,
    ) -> None:
        specs = {s.id: (i, s) for i, s in enumerate(scenario.sensors)}
        if sensor_id not in specs:
            raise ConfigError(
                f"sensor {sensor_id!r} is not a simulated sensor of this scenario "
                f"(known: {', '.join(specs) or 'none'})"
            )
        index, self.spec = specs[sensor_id]
        self.scenario = scenario
        self.name = f"sim:{scenario.name}:{sensor_id}"
        self.start_time = start_time
        self.speed = speed
        self.realtime = realtime
        self.clock = clock
        self.rate_hz = rate_hz or self.spec.rate_hz
        self.renderer = DepthRenderer(
            self.spec, scenario.room, np.random.default_rng([scenario.seed, 41, index])
        )
        self.intrinsics: Intrinsics | None = self.renderer.intrinsics
        self._stop = threading.Event()

    def frames(self) -> Iterator[Frame]:
        """Rendered frames with capture stamps on the sensor's (possibly offset) clock."""
        world = scenario_world(self.scenario)
        spec = self.spec
        end = self.scenario.duration_s
        k = 0
        while not self._stop.is_set():
            t = spec.phase_s + k / self.rate_hz
            if end is not None and t > end:
                return
            if self.realtime:
                due = self.start_time + t / self.speed
                wait = due - self.clock()
                if wait > 0:
                    if self._stop.wait(wait):
                        return
                else:
                    late = int(-wait * self.speed * self.rate_hz)
                    if late > 0:  # frames whose time has passed are never captured
                        k += late
                        continue
            snap = world.state_at(t)
            stamp = self.start_time + t + spec.clock_offset_s
            yield self.renderer.render(snap, stamp=stamp, seq=k).frame
            k += 1

    def close(self) -> None:
        """Stop producing frames."""
        self._stop.set()

    def __enter__(self) -> SimDepthSource:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()


class RenderedSensorModel:
    """A sensor simulated at the image level: render, then run the real detector.

    A drop-in for :class:`~openptrack_py.sim.sensors.SensorModel` in the
    :class:`~openptrack_py.sim.simulator.Simulator` (``sensor_model="rgbd"``), so that
    evaluation can score the whole chain, detector included, faster than real time.

    Parameters
    ----------
    spec : SensorSpec
        The sensor.
    room : Room
        The room.
    rng : numpy.random.Generator
        Rendering noise.
    config : DetectorConfig, optional
        Detector settings.
    """

    def __init__(
        self,
        spec: SensorSpec,
        room: Room,
        rng: np.random.Generator,
        config: DetectorConfig | None = None,
    ) -> None:
        self.spec = spec
        self.renderer = DepthRenderer(spec, room, rng)
        self.detector = PeopleDetector(
            config or DetectorConfig(),
            world_from_camera=world_from_optical(spec.pose),
            sensor_type=spec.type.name,
            rate_hz=spec.rate_hz,
            rng=np.random.default_rng(0),
        )
        self._coverage = SensorModel(spec, room, np.random.default_rng(0))

    def covers(self, pos: np.ndarray, height: np.ndarray) -> np.ndarray:
        """Mask of people whose head is in view (occlusion ignored)."""
        return self._coverage.covers(pos, height)

    def observe(self, snap: Snapshot) -> Observation:
        """Render ``snap`` and detect; person ids by nearest truth within 0.3 m (else 0)."""
        result = self.detector.detect(self.renderer.render(snap).frame)
        detections = tuple(d.to_detection() for d in result.detections)
        ids = []
        for d in detections:
            if len(snap):
                gap = np.hypot(snap.pos[:, 0] - d.x, snap.pos[:, 1] - d.y)
                best = int(np.argmin(gap))
                ids.append(int(snap.ids[best]) if gap[best] <= 0.3 else 0)
            else:
                ids.append(0)
        return Observation(detections, tuple(ids))
