"""A sensor simulated at the image level: render its view, then run the real detector.

The simulator's ``rgbd`` sensor model (:data:`~openptrack_py.sim.simulator.SENSOR_MODELS`):
slower than the detection-level model, but it scores the whole chain, detector included.
"""

from __future__ import annotations

import numpy as np

from openptrack_py.config import DetectorConfig
from openptrack_py.detection.pipeline import PeopleDetector
from openptrack_py.geometry import world_from_optical
from openptrack_py.sim.render import DepthRenderer
from openptrack_py.sim.sensors import Observation, SensorSpec
from openptrack_py.sim.visibility import SensorView
from openptrack_py.sim.world import Room, Snapshot


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
        self._coverage = SensorView(spec, room)

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
