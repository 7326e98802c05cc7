"""Appearance signature of a detection: a quantised colour histogram of its points.

The childcare tracking paper ("Simultaneous children recognition and tracking ... using
Kinect sensors", Eq. 8) compares children by hue histograms in HSV space. A hue-only
histogram says nothing about black, grey or white clothes, which are most of what people
wear, so the signature (:func:`colour_signatures`) has two parts:

* ``bins`` **hue bins**, equal sectors of 360 / ``bins`` degrees starting at red (0
  degrees), counting the pixels saturated and bright enough for hue to mean something
  (saturation >= ``min_saturation`` and value >= ``min_value``, HSV on 0-1);
* :data:`ACHROMATIC_BINS` = 3 **achromatic bins** after them, counting every other pixel
  by its value: dark (value < :data:`DARK_VALUE`), mid grey, light (value >=
  :data:`LIGHT_VALUE`).

So a signature has ``bins + 3`` entries (19 with the detector's default 16 hue bins),
normalised so that they sum to about 255 and quantised to integers 0-255; all zero only
when there were no colour pixels at all (no colour image). An identity model compares
signatures of the same length with the Bhattacharyya coefficient
(:func:`bhattacharyya`); it needs no more of the layout than that.

:func:`signature_bins` is the binning rule on HSV values, shared by the real detector
(through :func:`colour_signatures`) and the simulator's detection-level sensor model,
which builds signatures from the clothing colours of the people it sees.
"""

from __future__ import annotations

import numpy as np

ACHROMATIC_BINS = 3
"""Bins after the hue bins: dark, mid grey, light."""

DARK_VALUE = 0.3
"""Achromatic pixels darker than this (HSV value, 0-1) count as dark."""

LIGHT_VALUE = 0.7
"""Achromatic pixels at least this bright count as light."""

MIN_SATURATION = 0.2
"""Pixels less saturated than this carry no reliable hue (they are achromatic)."""

MIN_VALUE = 0.15
"""Pixels darker than this carry no reliable hue (they are achromatic, dark)."""


def signature_length(bins: int) -> int:
    """Entries of a signature with ``bins`` hue bins."""
    return bins + ACHROMATIC_BINS


def rgb_to_hsv(rgb: np.ndarray) -> np.ndarray:
    """HSV of RGB samples: hue in degrees ``[0, 360)``, saturation and value on 0-1.

    Parameters
    ----------
    rgb : ndarray
        ``(..., 3)`` RGB, uint8 (0-255) or floats on 0-1.
    """
    c = np.asarray(rgb)
    c = c.astype(np.float32) / 255.0 if c.dtype == np.uint8 else c.astype(np.float32)
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    value = c.max(axis=-1)
    chroma = value - c.min(axis=-1)
    safe = np.maximum(chroma, 1e-6)
    saturation = np.where(value > 0, chroma / np.maximum(value, 1e-6), 0.0)
    sector = np.where(
        value == r,
        ((g - b) / safe) % 6.0,
        np.where(value == g, (b - r) / safe + 2.0, (r - g) / safe + 4.0),
    )
    hue = np.where(chroma > 1e-6, sector * 60.0, 0.0) % 360.0
    return np.stack([hue, saturation, value], axis=-1)


def signature_bins(
    hue: np.ndarray,
    saturation: np.ndarray,
    value: np.ndarray,
    *,
    bins: int = 16,
    min_saturation: float = MIN_SATURATION,
    min_value: float = MIN_VALUE,
) -> np.ndarray:
    """Signature bin of each HSV sample (the layout of the module docstring).

    Parameters
    ----------
    hue : ndarray
        Hue, degrees (any real number; taken modulo 360).
    saturation, value : ndarray
        Saturation and value on 0-1.
    bins : int
        Hue bins.
    min_saturation, min_value : float
        Samples below either are achromatic.

    Returns
    -------
    ndarray
        Integer bin per sample, in ``[0, bins + 3)``.
    """
    hue = np.asarray(hue, dtype=float)
    value = np.asarray(value, dtype=float)
    chromatic = (np.asarray(saturation) >= min_saturation) & (value >= min_value)
    sector = np.minimum((np.mod(hue, 360.0) / 360.0 * bins).astype(np.int64), bins - 1)
    grey = np.where(value < DARK_VALUE, 0, np.where(value < LIGHT_VALUE, 1, 2))
    return np.where(chromatic, sector, bins + grey)


def colour_signatures(
    rgb: np.ndarray,
    labels: np.ndarray,
    count: int,
    *,
    bins: int = 16,
    min_saturation: float = MIN_SATURATION,
    min_value: float = MIN_VALUE,
) -> np.ndarray:
    """Quantised colour signatures (hue bins, then dark, grey, light) of labelled samples.

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
        Samples below either (HSV, 0-1) carry no reliable hue and go to the achromatic
        bins.

    Returns
    -------
    ndarray
        ``(count, bins + 3)`` uint8 signatures, each summing to about 255 (zero when the
        detection has no samples).
    """
    return normalise_signatures(_bin_counts(rgb, labels, count, bins, min_saturation, min_value))


def _bin_counts(
    rgb: np.ndarray,
    labels: np.ndarray,
    count: int,
    bins: int,
    min_saturation: float,
    min_value: float,
) -> np.ndarray:
    """``(count, bins + 3)`` sample counts per detection and signature bin."""
    width = signature_length(bins)
    keep = labels >= 0
    if count == 0 or not keep.any():
        return np.zeros((count, width), dtype=np.int64)
    hsv = rgb_to_hsv(rgb[keep])
    which = signature_bins(
        hsv[:, 0], hsv[:, 1], hsv[:, 2],
        bins=bins, min_saturation=min_saturation, min_value=min_value,
    )  # fmt: skip
    return np.bincount(labels[keep] * width + which, minlength=count * width).reshape(count, width)


def normalise_signatures(hist: np.ndarray) -> np.ndarray:
    """Rows of non-negative weights scaled to sum to about 255, as uint8 (zero rows stay)."""
    hist = np.asarray(hist, dtype=float)
    total = hist.sum(axis=1, keepdims=True)
    scaled = np.where(total > 0, hist * 255.0 / np.maximum(total, 1e-12), 0.0)
    return np.round(scaled).astype(np.uint8)


def hue_histograms(
    rgb: np.ndarray,
    labels: np.ndarray,
    count: int,
    *,
    bins: int = 16,
    min_saturation: float = MIN_SATURATION,
    min_value: float = MIN_VALUE,
) -> np.ndarray:
    """Quantised hue-only histograms of labelled colour samples (no achromatic bins).

    The hue part of :func:`colour_signatures`, renormalised: pixels without a reliable
    hue are skipped, so a grey or dark blob gives all zeros. Detections carry
    :func:`colour_signatures`; this is kept for callers that want hue alone.

    Returns
    -------
    ndarray
        ``(count, bins)`` uint8 histograms, each summing to about 255 (zero when none).
    """
    counts = _bin_counts(rgb, labels, count, bins, min_saturation, min_value)
    return normalise_signatures(counts[:, :bins])


def hue_correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of two hue histograms, in [-1, 1].

    The colour similarity of the childcare tracking paper.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    da, db = a - a.mean(), b - b.mean()
    denom = float(np.sqrt((da * da).sum() * (db * db).sum()))
    return float((da * db).sum() / denom) if denom > 0 else 0.0


def bhattacharyya(a: np.ndarray, b: np.ndarray) -> float:
    """Bhattacharyya coefficient of two signatures of the same length, in [0, 1].

    ``sum(sqrt(p * q))`` of the signatures normalised to sum to one; 1 for identical
    colour distributions, 0 for disjoint ones (and when either is all zero).
    """
    p = np.asarray(a, dtype=float)
    q = np.asarray(b, dtype=float)
    if p.shape != q.shape:
        raise ValueError(f"bhattacharyya: signatures of {p.shape} and {q.shape} differ")
    sp, sq = p.sum(), q.sum()
    if sp <= 0 or sq <= 0:
        return 0.0
    return float(np.sqrt(p / sp * (q / sq)).sum())
