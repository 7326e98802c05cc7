"""The detector on a bus: frames from a source in, DetectionBatch out.

:class:`DetectorService` is the body of the ``detector`` node. A grabber thread reads the
source and keeps only the newest frame: when detection falls behind, older frames are
dropped (counted as ``frames_dropped``), never queued. The node's loop detects people in
the newest frame and publishes a DetectionBatch on ``opt/<site>/detections/<sensor_id>``;
per-stage timings go into the node's stats. A sensor whose calibration entry holds its
own intrinsics (a checkerboard calibration with ``--refine-intrinsics``) is detected
through that camera model (pinhole and lens distortion) rather than the one its
frames report (a camera's factory figures, or its type's).
"""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np

from openptrack_py.config import DetectorConfig, NetworkConfig, SensorConfig
from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.detection.pipeline import PeopleDetector
from openptrack_py.detection.sources import Source, open_source
from openptrack_py.errors import ConfigError, SourceError
from openptrack_py.geometry import world_from_optical
from openptrack_py.messages.codec import encode_detection_batch
from openptrack_py.runtime.node import Inbox, Node
from openptrack_py.sensor_types import SENSOR_TYPES


def source_for_sensor(
    cfg: NetworkConfig,
    sensor: SensorConfig,
    spec: str | None = None,
    sim_source: Callable[[NetworkConfig, SensorConfig], Source] | None = None,
) -> Source:
    """Open the frame source of a network's sensor.

    ``sim`` sensors render the network's scenario (``sim.sensor_model: rgbd``) through
    ``sim_source`` (the simulator's, given by the caller: detection does not depend on
    the simulator); ``camera`` and ``recording`` sensors open ``spec`` or the sensor's
    ``input``. A recorded folder replays in real time at the sensor's rate (its frames
    keep their recorded stamps; the tracker's clock alignment absorbs the offset).

    Raises
    ------
    ConfigError
        When a camera or recording sensor says nowhere to read from, or a simulated
        sensor has no ``sim_source``.
    SourceError
        When the source cannot be opened.
    """
    if spec is None and sensor.source == "sim":
        if sim_source is None:
            raise ConfigError(
                f"sensors.{sensor.id}: a simulated sensor needs the simulator's frames "
                "(give an --input, or run it through the detector node)"
            )
        return sim_source(cfg, sensor)
    spec = spec or sensor.input or SENSOR_TYPES[sensor.type].live_input
    if spec is None:
        raise ConfigError(
            f"sensors.{sensor.id}.input: a {sensor.source} sensor needs an input "
            "(realsense[:SERIAL], azure-kinect[:N], a .bag, a folder or a cloud file)"
        )
    if sensor.source == "recording" and Path(spec).is_dir():
        # a recorded folder replays at the sensor's rate, as the sensor delivered it
        return open_source(spec, rate_hz=cfg.detector.rate_hz or sensor.rate_hz or 30.0)
    return open_source(spec)


class DetectorService:
    """Runs the people detector on one sensor's frames.

    Parameters
    ----------
    node : Node
        The node (bus, counters, stop flag).
    sensor : SensorConfig
        The sensor: id, type, pose, rate.
    config : DetectorConfig
        Detector settings.
    source : Source
        Where frames come from.
    calibration : (ndarray, float), optional
        The sensor's calibrated pose (4x4 ``world_from_optical``, instead of
        ``sensor.pose``) and clock offset (subtracted from the frames' stamps); updates
        are applied with :meth:`apply_calibration`.
    intrinsics : Intrinsics, optional
        The sensor's calibrated camera model (pinhole and lens distortion), used
        instead of each frame's (scaled to the frame's size when its shape is the same).
    """

    def __init__(
        self,
        node: Node,
        sensor: SensorConfig,
        config: DetectorConfig,
        source: Source,
        calibration: tuple[np.ndarray, float] | None = None,
        intrinsics: Intrinsics | None = None,
    ) -> None:
        self.node = node
        self.intrinsics = intrinsics
        self._shape_warned = False
        self.sensor = sensor
        self.source = source
        self.clock_offset_s = 0.0 if calibration is None else calibration[1]
        if calibration is not None:
            pose = calibration[0]
        elif sensor.pose is not None:  # a rendered sensor's simulated error is applied too
            pose = world_from_optical(sensor.pose_error.believed(sensor.pose))
        else:
            pose = None
        if pose is None:
            node.log.warning(
                "no pose: detections are reported in the sensor's floor frame",
                extra={"fields": {"sensor": sensor.id, "calibration": str(sensor.calibration)}},
            )
        self.detector = PeopleDetector(
            config,
            world_from_camera=pose,
            sensor_type=sensor.type,
            frame_id=sensor.id,
            rate_hz=config.rate_hz or sensor.rate_hz or 30.0,
            rng=np.random.default_rng(0),
        )
        counters = node.counters
        self._latest: Inbox[Frame] = Inbox(1, on_drop=lambda: counters.inc("frames_dropped"))
        self._publisher = node.publisher(node.keys.detections(sensor.id))
        self._grab_error: BaseException | None = None
        self._grab_done = threading.Event()
        self.seq = 0

    def apply_calibration(
        self,
        world_from_camera: np.ndarray,
        clock_offset_s: float,
        intrinsics: Intrinsics | None = None,
    ) -> None:
        """Use a new calibrated pose, clock offset and camera model from the next frame on."""
        self.detector.set_pose(world_from_camera)
        self.clock_offset_s = clock_offset_s
        self.intrinsics = intrinsics
        self.node.log.info("calibration applied", extra={"fields": {"sensor": self.sensor.id}})

    def _grab(self) -> None:
        try:
            for frame in self.source.frames():
                if not self.node.running:
                    break
                self.node.counters.inc("frames_in")
                self._latest.push(frame)
        except BaseException as exc:  # reported by run() in the node's thread
            self._grab_error = exc
        finally:
            self._grab_done.set()

    def step(self, frame: Frame, on_result: Callable[[int], None] | None = None) -> None:
        """Detect in one frame and publish the batch."""
        counters = self.node.counters
        result = self.detector.detect(self._calibrated(frame))
        for stage, seconds in result.timings.items():
            counters.add_timing(stage, seconds)
        batch = result.to_batch(self.sensor.id, self.seq, frame.stamp - self.clock_offset_s)
        self.seq += 1
        self._publisher.put(encode_detection_batch(batch))
        counters.inc("batches")
        counters.inc("detections", len(batch.detections))
        if result.status != "ok":
            counters.inc(f"status_{result.status.replace('-', '_')}")

    def _calibrated(self, frame: Frame) -> Frame:
        """The frame with the calibrated camera model, if any (at the frame's image size).

        A frame of another shape (another image mode, cropped rather than scaled) keeps
        its own pinhole, with one warning.
        """
        own, k = frame.intrinsics, self.intrinsics
        if k is None or own is None:
            return frame
        if (k.width, k.height) != (own.width, own.height):
            if abs(k.width * own.height / (k.height * own.width) - 1.0) > 0.01:
                if not self._shape_warned:
                    self._shape_warned = True
                    self.node.log.warning(
                        "calibrated intrinsics are for %dx%d images, frames are %dx%d: "
                        "using the frames' own",
                        k.width, k.height, own.width, own.height,
                    )  # fmt: skip
                return frame
            k = k.scaled(own.width, own.height)
        return dataclasses.replace(frame, intrinsics=k)

    def run(self) -> None:
        """Detect until the source ends or the node is stopped.

        Raises
        ------
        SourceError
            When the source fails (the launcher restarts the node with back-off).
        """
        log = self.node.log
        log.info(
            "detecting",
            extra={
                "fields": {"sensor": self.sensor.id, "source": getattr(self.source, "name", "")}
            },
        )
        grabber = threading.Thread(target=self._grab, name="grab", daemon=True)
        grabber.start()
        try:
            while self.node.running:
                frame = self._latest.get(timeout=0.2)
                if frame is None:
                    if self._grab_done.is_set() and len(self._latest) == 0:
                        break
                    continue
                self.step(frame)
        finally:
            self.source.close()
            grabber.join(timeout=2.0)
        if self._grab_error is not None:
            if isinstance(self._grab_error, SourceError):
                log.error("source failed: %s", self._grab_error)
            raise self._grab_error
