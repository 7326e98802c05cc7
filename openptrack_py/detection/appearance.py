"""Appearance signature of a detection: a quantised hue histogram of its colour points.

The childcare tracking paper ("Simultaneous children recognition and tracking ... using
Kinect sensors", Eq. 8) compares children by the correlation of hue histograms in HSV
space. Each detection carries such a histogram: hue in ``bins`` equal sectors, counting only
pixels saturated and bright enough for hue to mean something, normalised so that the
bins sum to about 255 and quantised to integers 0-255 (an all-zero signature means no
usable colour, e.g. a grey or dark blob, or no colour image).
"""

from __future__ import annotations

import numpy as np


def hue_histograms(
    rgb: np.ndarray,
    labels: np.ndarray,
    count: int,
    *,
    bins: int = 16,
    min_saturation: float = 0.2,
    min_value: float = 0.15,
) -> np.ndarray:
    """Quantised hue histograms of labelled colour samples.

    Parameters
    ----------
    rgb : ndarray
        ``(n, 3)`` uint8 RGB samples.
    labels : ndarray
        ``(n,)`` detection index of each sample (samples with a negative label are ignored).
    count : int
        Number of detections.
    bins : int
        Hue sectors.
    min_saturation, min_value : float
        Samples below either (HSV, 0-1) carry no reliable hue and are skipped.

    Returns
    -------
    ndarray
        ``(count, bins)`` uint8 histograms, each summing to about 255 (zero when none).
    """
    out = np.zeros((count, bins), dtype=np.uint8)
    keep = labels >= 0
    if count == 0 or not keep.any():
        return out
    c = rgb[keep].astype(np.float32) / 255.0
    lab = labels[keep]
    r, g, b = c[:, 0], c[:, 1], c[:, 2]
    value = c.max(axis=1)
    chroma = value - c.min(axis=1)
    saturation = np.where(value > 0, chroma / np.maximum(value, 1e-6), 0.0)
    good = (saturation >= min_saturation) & (value >= min_value) & (chroma > 1e-6)
    if not good.any():
        return out
    r, g, b, value, chroma, lab = r[good], g[good], b[good], value[good], chroma[good], lab[good]
    hue = np.where(
        value == r,
        ((g - b) / chroma) % 6.0,
        np.where(value == g, (b - r) / chroma + 2.0, (r - g) / chroma + 4.0),
    )
    sector = np.minimum((hue / 6.0 * bins).astype(np.int64), bins - 1)
    hist = np.bincount(lab * bins + sector, minlength=count * bins).reshape(count, bins)
    total = hist.sum(axis=1, keepdims=True)
    scaled = np.where(total > 0, hist * 255.0 / np.maximum(total, 1), 0.0)
    return np.round(scaled).astype(np.uint8)


def hue_correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of two hue histograms, in [-1, 1].

    The colour similarity of the childcare tracking paper.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    da, db = a - a.mean(), b - b.mean()
    denom = float(np.sqrt((da * da).sum() * (db * db).sum()))
    return float((da * db).sum() / denom) if denom > 0 else 0.0
