"""A rendered simulated sensor as a depth source (``sensor_model: rgbd``).

:class:`SimDepthSource` plays a scenario's world and renders one sensor's view at that
sensor's rate; :func:`sim_source_for_sensor` opens it for a network file's simulated
sensor, which is how a detector node runs on the simulator. Every process that
simulates part of a scenario builds the same world from the same seed, so a detector
node rendering its sensor and the ``sim`` node publishing ground truth agree on where
everybody is, given a shared ``start_time``.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator

import numpy as np

from openptrack_py.config import NetworkConfig, SensorConfig
from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.errors import ConfigError
from openptrack_py.sim.live import scenario_from_network
from openptrack_py.sim.render import DepthRenderer
from openptrack_py.sim.scenarios import Scenario, scenario_world


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
        self.intrinsics: Intrinsics | None = self.renderer.reports
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


def sim_source_for_sensor(cfg: NetworkConfig, sensor: SensorConfig) -> SimDepthSource:
    """The rendered frames of a network's ``source: sim`` sensor, in real time.

    Every process builds the network's scenario from the same seed and starts it at
    ``sim.start_time`` (now if unset), so renderings agree with the ``sim`` node's truth.

    Raises
    ------
    ConfigError
        If the network has no ``sim`` section or the sensor is not simulated.
    """
    scenario = scenario_from_network(cfg, calibrated=False)  # the renderer uses true poses
    assert cfg.sim is not None  # scenario_from_network checked it
    start = cfg.sim.start_time if cfg.sim.start_time is not None else time.time()
    return SimDepthSource(
        scenario,
        sensor.id,
        start_time=start,
        speed=cfg.sim.speed,
        rate_hz=cfg.detector.rate_hz,
    )
