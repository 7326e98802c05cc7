"""People detection from depth: sources, floor, background, blobs, HOG check, appearance.

What runs on each sensor machine: a :class:`~openptrack_py.detection.sources.Source`
yields :class:`~openptrack_py.detection.frame.Frame` objects and a
:class:`~openptrack_py.detection.pipeline.PeopleDetector` turns each into detections.
Only numpy and scipy are needed for detection; reading files and devices and the HOG
check need the ``[sensor]`` extra (open3d, OpenCV), imported when used.
"""

from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.detection.ground import GroundPlane
from openptrack_py.detection.pipeline import DetectionResult, PeopleDetector, PersonDetection

__all__ = [
    "DetectionResult",
    "Frame",
    "GroundPlane",
    "Intrinsics",
    "PeopleDetector",
    "PersonDetection",
]
