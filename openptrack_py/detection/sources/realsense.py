"""Intel RealSense cameras through open3d: ``.bag`` recordings and live devices."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.detection.sources.base import (
    DEFAULT_DEPTH_SCALE,
    _clean,
    _depth_from_o3d,
    _depth_to_metres,
    _import_open3d,
    _LiveSource,
    _rgb_from_o3d,
    _SourceBase,
)
from openptrack_py.errors import ConfigError, SourceError


class RealSenseBagSource(_SourceBase):
    """A RealSense ``.bag`` recording, read with ``open3d.t.io.RSBagReader``.

    Depth is aligned to the colour stream by the reader, so the intrinsics are the colour
    camera's. Stamps are the playback position, seconds from the start of the recording.
    The reader's metadata carries the pinhole only (``RGBDVideoMetadata.intrinsics``, an
    ``open3d.camera.PinholeCameraIntrinsic``), not the stream's lens terms, so frames
    report no distortion; a sensor's lens comes from its calibration file's
    ``intrinsics`` (``openptrack calibrate checkerboard --refine-intrinsics`` solves it).

    Parameters
    ----------
    path : str or Path
        The ``.bag`` file.

    Raises
    ------
    SourceError
        The file is missing or not a RealSense recording with a depth and a colour stream
        (the message names the file), or open3d is missing.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.name = str(path)
        if not self.path.is_file():
            raise SourceError(f"{self.name}: no such file")
        o3d = _import_open3d(self.name)
        self._reader = o3d.t.io.RSBagReader()
        try:
            opened = self._reader.open(str(self.path))
        except RuntimeError as exc:
            raise SourceError(
                f"{self.name}: cannot open the RealSense recording ({_clean(exc)})"
            ) from None
        if not opened:
            raise SourceError(
                f"{self.name}: cannot open the RealSense recording (not a RealSense .bag, "
                "or it lacks a depth (Z16) or a colour stream)"
            )
        meta = self._reader.metadata
        try:
            self.intrinsics = _intrinsics_from_o3d(meta.intrinsics, meta.width, meta.height)
        except ConfigError as exc:
            self._reader.close()
            raise SourceError(
                f"{self.name}: invalid intrinsics in the recording ({exc})"
            ) from None
        self.depth_scale = _o3d_depth_scale(meta)
        self.fps = float(meta.fps)
        self._color_format = str(meta.color_format)
        self._open = True

    def frames(self) -> Iterator[Frame]:
        """The recording's frames until its end.

        Yields
        ------
        Frame
            Organised frames with depth in metres (NaN where zero) and RGB colour.
        """
        seq = 0
        while self._open and not self._reader.is_eof():
            try:
                rgbd = self._reader.next_frame()
            except RuntimeError as exc:
                raise SourceError(f"{self.name}: cannot read a frame ({_clean(exc)})") from None
            raw = _depth_from_o3d(rgbd.depth)
            if raw is None:  # the reader returns an empty image at the end
                continue
            stamp = self._reader.get_timestamp() / 1e6
            depth = _depth_to_metres(raw, self.depth_scale, self.name)
            color = _rgb_from_o3d(rgbd.color, self._color_format)
            yield Frame(stamp=stamp, seq=seq, intrinsics=self.intrinsics, depth=depth, color=color)
            seq += 1

    def close(self) -> None:
        """Close the recording."""
        if self._open:
            self._open = False
            self._reader.close()


class RealSenseSource(_LiveSource):
    """A live RealSense camera through ``open3d.t.io.RealSenseSensor``.

    Depth is aligned to colour; stamps are the host's UNIX time at capture, so frames of
    several sensors compare directly.

    Parameters
    ----------
    serial : str, optional
        Serial number of the camera; the first one found by default.
    config : mapping of str to str, optional
        Extra ``RealSenseSensorConfig`` entries (e.g. ``{"color_resolution": "640,480"}``).

    Raises
    ------
    SourceError
        No camera (or none with this serial) is connected, it cannot be started, or open3d
        is missing.
    """

    def __init__(
        self, serial: str | None = None, *, config: Mapping[str, str] | None = None
    ) -> None:
        self.serial = serial
        self.name = "realsense" + (f":{serial}" if serial else "")
        o3d = _import_open3d(self.name)
        sensor_cls = o3d.t.io.RealSenseSensor
        try:
            devices = sensor_cls.enumerate_devices()
        except RuntimeError as exc:
            raise SourceError(
                f"realsense: no RealSense device found (cannot list devices: {_clean(exc)})"
            ) from None
        serials = [str(getattr(d, "serial", "")) for d in devices]
        connected = ", ".join(s or "?" for s in serials) or "none"
        if not devices:
            raise SourceError(
                "realsense: no RealSense device found (connected: none); plug one in (USB 3) "
                "or replay a recording with a .bag file"
            )
        if serial is not None and serial not in serials:
            raise SourceError(
                f"realsense: no RealSense device with serial {serial} found "
                f"(connected: {connected})"
            )
        settings = dict(config or {})
        if serial is not None:
            settings["serial"] = serial
        self._sensor = sensor_cls()
        try:
            ok = self._sensor.init_sensor(o3d.t.io.RealSenseSensorConfig(settings), 0, "")
            ok = ok and self._sensor.start_capture(False)
        except RuntimeError as exc:
            raise SourceError(f"{self.name}: cannot start the camera ({_clean(exc)})") from None
        if not ok:
            raise SourceError(f"{self.name}: cannot start the camera (connected: {connected})")
        meta = self._sensor.get_metadata()
        self.intrinsics = _intrinsics_from_o3d(meta.intrinsics, meta.width, meta.height)
        self.depth_scale = _o3d_depth_scale(meta)
        self._color_format = str(meta.color_format)
        self._open = True

    def _capture(self) -> tuple[np.ndarray, np.ndarray | None] | None:
        try:
            rgbd = self._sensor.capture_frame(True, True)
        except RuntimeError as exc:
            raise SourceError(f"{self.name}: capture failed ({_clean(exc)})") from None
        raw = _depth_from_o3d(rgbd.depth)
        if raw is None:
            return None
        depth = _depth_to_metres(raw, self.depth_scale, self.name)
        return depth, _rgb_from_o3d(rgbd.color, self._color_format)

    def close(self) -> None:
        """Stop the capture."""
        if getattr(self, "_open", False):
            self._open = False
            self._sensor.stop_capture()


def _intrinsics_from_o3d(pinhole: Any, width: int = 0, height: int = 0) -> Intrinsics:
    """:class:`Intrinsics` from an ``open3d.camera.PinholeCameraIntrinsic``."""
    k = np.asarray(pinhole.intrinsic_matrix, dtype=float)
    return Intrinsics.from_matrix(k, pinhole.width or width, pinhole.height or height)


def _o3d_depth_scale(meta: Any) -> float:
    """Depth units per metre of an open3d RealSense metadata (millimetres if unset)."""
    return float(meta.depth_scale) if meta.depth_scale > 0 else DEFAULT_DEPTH_SCALE
