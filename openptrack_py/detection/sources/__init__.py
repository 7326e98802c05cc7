"""Sources of depth frames behind one interface, one module per kind of source.

Every source yields :class:`~openptrack_py.detection.frame.Frame` objects in the camera's
optical frame (x right, y down, z forward, metres; NaN where the depth is invalid):

* :class:`FolderSource` (:mod:`.folder`): a folder written by :func:`record_folder`
  (:mod:`.recording`), a TUM RGB-D sequence, or a plain folder of depth PNGs;
* :class:`CloudSource` (:mod:`.cloud`): a ``.pcd`` or ``.ply`` point cloud (or a folder
  of them);
* :class:`RealSenseBagSource` and :class:`RealSenseSource` (:mod:`.realsense`): a
  RealSense ``.bag`` recording, a live RealSense camera;
* :class:`AzureKinectSource` (:mod:`.azure_kinect`): a live Azure Kinect.

:func:`open_source` (:mod:`.factory`) picks one from a text spec; the interface and the
helpers the kinds share are in :mod:`.base`. open3d and OpenCV are imported only when a
source needs them, so importing this package costs nothing; without them the sources raise
:class:`~openptrack_py.errors.SourceError` saying how to install them.
"""

from openptrack_py.detection.sources.azure_kinect import AzureKinectSource
from openptrack_py.detection.sources.base import DEFAULT_DEPTH_SCALE, INSTALL_HINT, Source
from openptrack_py.detection.sources.cloud import (
    CLOUD_SUFFIXES,
    MAX_PINHOLE_RESIDUAL_PX,
    CloudSource,
    read_cloud,
)
from openptrack_py.detection.sources.factory import open_source
from openptrack_py.detection.sources.folder import (
    PLAIN_RATE_HZ,
    TUM_DEFAULT_INTRINSICS,
    TUM_DEPTH_SCALE,
    TUM_MAX_COLOR_DT,
    FolderSource,
)
from openptrack_py.detection.sources.realsense import RealSenseBagSource, RealSenseSource
from openptrack_py.detection.sources.recording import record_folder
from openptrack_py.errors import SourceError

__all__ = [
    "CLOUD_SUFFIXES",
    "DEFAULT_DEPTH_SCALE",
    "INSTALL_HINT",
    "MAX_PINHOLE_RESIDUAL_PX",
    "PLAIN_RATE_HZ",
    "TUM_DEFAULT_INTRINSICS",
    "TUM_DEPTH_SCALE",
    "TUM_MAX_COLOR_DT",
    "AzureKinectSource",
    "CloudSource",
    "FolderSource",
    "RealSenseBagSource",
    "RealSenseSource",
    "Source",
    "SourceError",
    "open_source",
    "read_cloud",
    "record_folder",
]
