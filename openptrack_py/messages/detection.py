"""Person detections from one sensor frame."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Detection:
    """One person detected in one sensor frame.

    Parameters
    ----------
    x, y, z : float
        Centroid in metres, in the batch's ``frame_id`` (``world``: x, y on the floor,
        z up).
    height : float
        Top of the person above the floor, metres.
    confidence : float
        Detector confidence in ``[0, 1]``: 0 = certainly not a person, 1 = certainly a
        person. Detectors map their native scores (HOG margins, cluster shape scores)
        onto this scale.
    distance : float
        Range from the sensor to the centroid, metres.
    bbox : tuple of int, optional
        Image box ``(u, v, width, height)`` in pixels of the sensor's depth image.
    appearance : tuple of int, optional
        Appearance signature: a small quantised colour histogram (each bin 0-255).
    face : tuple of float, optional
        Face embedding, when a face recogniser ran.
    """

    x: float
    y: float
    z: float
    height: float
    confidence: float
    distance: float
    bbox: tuple[int, int, int, int] | None = None
    appearance: tuple[int, ...] | None = None
    face: tuple[float, ...] | None = None


@dataclass(frozen=True, slots=True)
class DetectionBatch:
    """Every detection of one sensor frame (possibly none).

    Parameters
    ----------
    sensor_id : str
        Identifier of the sensor, as in the network file.
    seq : int
        Per-sensor frame counter, starting at 0, increasing by one per frame.
    stamp : float
        Capture time of the frame, UNIX seconds on the sensor's clock.
    frame_id : str
        ``"world"`` once the sensor is calibrated, else the sensor's own frame.
    detections : tuple of Detection
        The people seen in this frame.
    """

    sensor_id: str
    seq: int
    stamp: float
    frame_id: str
    detections: tuple[Detection, ...] = ()
