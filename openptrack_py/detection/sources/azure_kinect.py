"""A live Microsoft Azure Kinect through open3d (needs the Azure Kinect SDK, libk4a)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from openptrack_py.detection.frame import Intrinsics
from openptrack_py.detection.sources.base import (
    DEFAULT_DEPTH_SCALE,
    _clean,
    _depth_from_o3d,
    _depth_to_metres,
    _import_open3d,
    _LiveSource,
    _rgb_from_o3d,
)
from openptrack_py.errors import SourceError
from openptrack_py.sensor_types import AZURE_KINECT

# Nominal horizontal field of view of the Azure Kinect colour camera (all resolutions).


class AzureKinectSource(_LiveSource):
    """A live Azure Kinect through ``open3d.io.AzureKinectSensor`` (needs the k4a SDK).

    Depth is aligned to the colour camera. open3d does not expose the factory calibration,
    so unless ``intrinsics`` is given they are nominal (90 degree horizontal field of view,
    square pixels, centred principal point) for the delivered image size. Stamps are the
    host's UNIX time at capture.

    Parameters
    ----------
    device : int
        Index of the device.
    intrinsics : Intrinsics, optional
        Calibrated intrinsics of the colour camera at the delivered resolution.
    config : mapping of str to str, optional
        ``AzureKinectSensorConfig`` entries (e.g. ``{"color_resolution":
        "K4A_COLOR_RESOLUTION_720P"}``).

    Raises
    ------
    SourceError
        No device (or the SDK is not installed), or open3d is missing.
    """

    def __init__(
        self,
        device: int = 0,
        *,
        intrinsics: Intrinsics | None = None,
        config: Mapping[str, str] | None = None,
    ) -> None:
        self.device = int(device)
        self.name = f"azure-kinect:{self.device}"
        self.intrinsics = intrinsics
        o3d = _import_open3d(self.name)
        # Without the SDK, open3d's sensor object aborts the process when it is destroyed
        # (its destructor throws), so it must not be created at all.
        missing = _k4a_library_error()
        if missing is not None:
            raise SourceError(
                f"azure-kinect: no Azure Kinect device found (device {self.device}; the Azure "
                f"Kinect SDK library cannot be loaded: {missing}); install the SDK (libk4a) "
                "and connect a device"
            )
        try:
            sensor_config = o3d.io.AzureKinectSensorConfig(dict(config or {}))
            self._sensor = o3d.io.AzureKinectSensor(sensor_config)
            connected = self._sensor.connect(self.device)
        except RuntimeError as exc:
            raise SourceError(
                f"azure-kinect: no Azure Kinect device found (device {self.device}; {_clean(exc)})"
            ) from None
        if not connected:
            raise SourceError(
                f"azure-kinect: no Azure Kinect device found (device {self.device} did not "
                "connect); plug one in or check it is not in use"
            )
        self._open = True

    def _capture(self) -> tuple[np.ndarray, np.ndarray | None] | None:
        try:
            rgbd = self._sensor.capture_frame(True)
        except RuntimeError as exc:
            raise SourceError(f"{self.name}: capture failed ({_clean(exc)})") from None
        raw = None if rgbd is None else _depth_from_o3d(rgbd.depth)
        if raw is None:
            return None
        if raw.dtype.kind == "f":  # already metres
            depth = raw.astype(np.float32)
            depth[~(depth > 0)] = np.nan
        else:
            depth = _depth_to_metres(raw, DEFAULT_DEPTH_SCALE, self.name)
        if self.intrinsics is None:
            height, width = depth.shape
            self.intrinsics = Intrinsics(width, height, *AZURE_KINECT.intrinsics_at(width, height))
        return depth, _rgb_from_o3d(rgbd.color)

    def close(self) -> None:
        """Disconnect the device."""
        if getattr(self, "_open", False):
            self._open = False
            self._sensor.disconnect()


def _k4a_library_error() -> str | None:
    """Why the Azure Kinect SDK library cannot be loaded the way open3d loads it, or ``None``."""
    import ctypes
    import os
    import sys

    if sys.platform == "win32":
        name = "k4a.dll"
        folders = [os.environ.get("K4A_LIB_DIR", ""), ""]
    else:
        name = "libk4a.so"
        folders = ["", *(d for d in os.environ.get("LD_LIBRARY_PATH", "").split(":") if d)]
    reason = f"{name} not found"
    for folder in folders:
        try:
            ctypes.CDLL(os.path.join(folder, name) if folder else name)
        except OSError as exc:
            reason = str(exc)
        else:
            return None
    return reason
