"""OpenCV, the optional dependency of the checkerboard calibration, loaded on first use.

Corner detection, the board's pose and the intrinsics of the checkerboard calibration
(Munaro et al., OpenPTrack, §4) run on OpenCV (``pip install 'openptrack_py[sensor]'``).
It is imported by :func:`opencv`, inside the functions that need it and never at module
import, so the board geometry and the pose solvers are available without it.
"""

from __future__ import annotations

from typing import Any

from openptrack_py.errors import CalibrationError

__all__ = ["opencv"]


def opencv() -> Any:
    """OpenCV's ``cv2`` module.

    Returns
    -------
    module
        ``cv2``.

    Raises
    ------
    CalibrationError
        Saying how to install it, when it is missing.
    """
    try:
        import cv2
    except ImportError:  # pragma: no cover - depends on the installed extras
        raise CalibrationError(
            "checkerboard calibration needs OpenCV (pip install 'openptrack_py[sensor]')"
        ) from None
    return cv2
