"""HOG person check: OpenCV's people detector applied at each blob's image box.

OpenPTrack scores each depth blob with a HOG+SVM classifier on the RGB image (on the
infrared image for Kinect v2 and SR4500, after histogram equalisation) and skips the
colour check when the image is too dark (mean luminance below ``minimum_luminance``).
This is the same rule with OpenCV's default Dalal-Triggs people detector (64x128 window):
the score of a box is the linear SVM's margin ``w . hog(box) + b`` — positive means
"person" — computed on the box padded to the window's 1:2 aspect with the person filling
the middle three quarters, as in the detector's training windows.

Needs ``opencv-python-headless`` (``pip install openptrack_py[sensor]``).
"""

from __future__ import annotations

import math

import numpy as np

from openptrack_py.errors import ConfigError

WINDOW = (64, 128)


def _cv2():
    try:
        import cv2
    except ImportError:  # pragma: no cover - depends on the installed extras
        raise ConfigError(
            "detector.hog.enabled: the HOG check needs OpenCV "
            "(pip install 'openptrack_py[sensor]')"
        ) from None
    return cv2


def luminance(rgb: np.ndarray) -> float:
    """Mean luma (ITU-R BT.601, 0-255) of an RGB image."""
    sub = rgb[::4, ::4].astype(np.float32)
    return float((sub @ np.array([0.299, 0.587, 0.114], dtype=np.float32)).mean())


def equalised_ir(intensity: np.ndarray) -> np.ndarray:
    """An infrared/amplitude image as 8-bit with its histogram equalised."""
    cv2 = _cv2()
    img = intensity.astype(np.float32)
    high = float(np.percentile(img, 99.5)) or 1.0
    img8 = np.clip(img * (255.0 / high), 0, 255).astype(np.uint8)
    return cv2.equalizeHist(img8)


class HogVerifier:
    """Scores image boxes with OpenCV's HOG people detector."""

    def __init__(self) -> None:
        cv2 = _cv2()
        self._cv2 = cv2
        self._hog = cv2.HOGDescriptor()
        detector = np.asarray(cv2.HOGDescriptor.getDefaultPeopleDetector(), dtype=np.float32)
        self._weights = detector[:-1].ravel()
        self._bias = float(detector[-1])

    def gray(self, rgb: np.ndarray) -> np.ndarray:
        """8-bit grey image of an RGB image."""
        return self._cv2.cvtColor(rgb, self._cv2.COLOR_RGB2GRAY)

    def window(self, gray: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray | None:
        """The 64x128 detection window around an image box ``(u, v, w, h)``; None if empty."""
        u, v, w, h = box
        if w < 2 or h < 4:
            return None
        # The person fills the central ~3/4 of a 1:2 window.
        height = h / 0.75
        width = max(height / 2, w / 0.75)
        height = max(height, 2 * width)
        cu, cv = u + w / 2, v + h / 2
        u0, v0 = math.floor(cu - width / 2), math.floor(cv - height / 2)
        u1, v1 = math.ceil(cu + width / 2), math.ceil(cv + height / 2)
        rows, cols = gray.shape[:2]
        pad = (max(0, -v0), max(0, v1 - rows), max(0, -u0), max(0, u1 - cols))
        crop = gray[max(v0, 0) : min(v1, rows), max(u0, 0) : min(u1, cols)]
        if crop.size == 0:
            return None
        if any(pad):
            crop = self._cv2.copyMakeBorder(crop, *pad, self._cv2.BORDER_REPLICATE)
        return self._cv2.resize(crop, WINDOW, interpolation=self._cv2.INTER_AREA)

    def score(self, gray: np.ndarray, boxes: list[tuple[int, int, int, int]]) -> np.ndarray:
        """SVM margin per box (``-inf`` for boxes with nothing to look at)."""
        out = np.full(len(boxes), -np.inf)
        for k, box in enumerate(boxes):
            win = self.window(gray, box)
            if win is None:
                continue
            desc = self._hog.compute(win)
            out[k] = float(desc.ravel() @ self._weights) + self._bias
        return out


def margin_to_confidence(margin: np.ndarray) -> np.ndarray:
    """Map SVM margins to ``[0, 1]``: a logistic with 0.5 at the decision boundary."""
    return 1.0 / (1.0 + np.exp(-2.0 * np.asarray(margin, dtype=float)))
