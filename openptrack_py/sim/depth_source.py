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

from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.errors import ConfigError
from openptrack_py.sim.render import DepthRenderer
from openptrack_py.sim.scenarios import Scenario
from openptrack_py.sim.world import World


def scenario_world(scenario: Scenario) -> World:
    """The scenario's world, seeded exactly as :class:`~openptrack_py.sim.simulator.Simulator` does."""
    world_seq, _ = np.random.SeedSequence(scenario.seed).spawn(2)
    rng = np.random.default_rng(world_seq)
    return World(scenario.room, scenario.make_director(rng), rng)


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
    realtime : bool
        Pace frames by the clock, skipping frames that are already past when behind
        (a live sensor does not wait for its consumer); otherwise render every frame at
        once.
    clock, sleep : callable
        Time source and sleep, for tests.

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
        self.renderer = DepthRenderer(
            self.spec, scenario.room, np.random.default_rng([scenario.seed, 41, index])
        )
        self.intrinsics: Intrinsics | None = self.renderer.intrinsics
        self.skipped = 0
        self._stop = threading.Event()

    def frames(self) -> Iterator[Frame]:
        """Rendered frames with capture stamps on the sensor's (possibly offset) clock."""
        world = scenario_world(self.scenario)
        spec = self.spec
        end = self.scenario.duration_s
        k = 0
        while not self._stop.is_set():
            t = spec.phase_s + k / spec.rate_hz
            if end is not None and t > end:
                return
            if self.realtime:
                due = self.start_time + t / self.speed
                wait = due - self.clock()
                if wait > 0:
                    if self._stop.wait(wait):
                        return
                else:
                    late = int(-wait * self.speed * spec.rate_hz)
                    if late > 0:  # frames whose time has passed are never captured
                        self.skipped += late
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
