"""What simulated people wear: clothing colour palettes and school uniforms.

People mostly wear black, grey, white, navy and denim, with fewer saturated colours, so
colour alone tells fewer people apart than uniformly drawn hues would suggest. The
palettes below say how often each colour is worn on top (:data:`TOP_PALETTE`) and below
(:data:`BOTTOM_PALETTE`). Their shares are an **assumption** (many people in black,
grey, navy and denim; jeans the commonest trousers), not a published survey.

A colour is ``(hue, saturation, value)``: hue in degrees, saturation and value on 0-1
(HSV, as the renderer paints it and as appearance signatures bin it,
:mod:`openptrack_py.detection.appearance`).

:func:`clothing_colour` maps one uniform number in ``[0, 1)`` onto a palette: the inverse
of the palette's cumulative shares picks the colour and the rest of the number, rescaled
to ``[0, 1)``, a small shade variation (lighter or darker, a few degrees of hue, more or
less saturated). One uniform per garment, so the world draws exactly what it drew when
clothes were uniformly random hues.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

HSV = tuple[float, float, float]
"""A colour: hue (degrees), saturation (0-1), value (0-1)."""

SKIN: HSV = (25.0, 0.45, 0.85)
"""Skin as the renderer paints it (one tone for everyone)."""

HAIR: HSV = (24.0, 0.56, 0.18)
"""Hair as the renderer paints it."""


@dataclass(frozen=True)
class PaletteColour:
    """One colour of a clothing palette.

    Parameters
    ----------
    name : str
        What it is called.
    hsv : tuple of float
        Its typical ``(hue, saturation, value)``.
    share : float
        Fraction of garments of this colour.
    """

    name: str
    hsv: HSV
    share: float


BLACK: HSV = (0.0, 0.05, 0.1)
DARK_GREY: HSV = (210.0, 0.06, 0.28)
GREY: HSV = (0.0, 0.03, 0.55)
WHITE: HSV = (45.0, 0.04, 0.92)
NAVY: HSV = (225.0, 0.6, 0.28)
DENIM: HSV = (215.0, 0.5, 0.47)

TOP_PALETTE: tuple[PaletteColour, ...] = (
    PaletteColour("black", BLACK, 0.20),
    PaletteColour("dark grey", DARK_GREY, 0.08),
    PaletteColour("grey", GREY, 0.08),
    PaletteColour("white", WHITE, 0.14),
    PaletteColour("navy", NAVY, 0.10),
    PaletteColour("denim blue", (212.0, 0.45, 0.55), 0.06),
    PaletteColour("light blue", (205.0, 0.3, 0.82), 0.04),
    PaletteColour("beige", (38.0, 0.28, 0.76), 0.05),
    PaletteColour("brown", (25.0, 0.5, 0.35), 0.03),
    PaletteColour("olive", (75.0, 0.4, 0.4), 0.03),
    PaletteColour("burgundy", (345.0, 0.65, 0.38), 0.03),
    PaletteColour("red", (355.0, 0.78, 0.72), 0.04),
    PaletteColour("green", (140.0, 0.55, 0.45), 0.03),
    PaletteColour("yellow", (48.0, 0.7, 0.85), 0.02),
    PaletteColour("orange", (24.0, 0.8, 0.88), 0.02),
    PaletteColour("pink", (340.0, 0.35, 0.88), 0.03),
    PaletteColour("purple", (275.0, 0.45, 0.45), 0.02),
)
"""Tops (shirts, jumpers, jackets): half achromatic, a tenth navy, few bright colours."""

BOTTOM_PALETTE: tuple[PaletteColour, ...] = (
    PaletteColour("denim blue", DENIM, 0.30),
    PaletteColour("black", BLACK, 0.25),
    PaletteColour("dark grey", DARK_GREY, 0.10),
    PaletteColour("navy", NAVY, 0.08),
    PaletteColour("grey", GREY, 0.06),
    PaletteColour("khaki", (38.0, 0.32, 0.68), 0.10),
    PaletteColour("brown", (25.0, 0.5, 0.33), 0.04),
    PaletteColour("olive", (75.0, 0.4, 0.38), 0.03),
    PaletteColour("white", WHITE, 0.02),
    PaletteColour("red", (355.0, 0.7, 0.6), 0.01),
    PaletteColour("green", (140.0, 0.5, 0.4), 0.01),
)
"""Trousers and skirts: mostly jeans and black, then greys, khaki and navy."""

SCHOOL_UNIFORMS: tuple[tuple[HSV, HSV], ...] = ((NAVY, GREY), (WHITE, NAVY))
"""Two school-uniform ``(top, bottom)`` combinations: navy over grey, white over navy."""

# Shade variation: value within +-12 %, hue within +-6 degrees, saturation within +-10 %.
_VALUE_SPREAD = 0.25
_HUE_SPREAD_DEG = 12.0
_SATURATION_SPREAD = 0.2


def _pick(u: float, palette: tuple[PaletteColour, ...]) -> tuple[int, float]:
    """Index of the palette colour ``u`` falls on, and where in its interval (0-1)."""
    shares = np.array([c.share for c in palette], dtype=float)
    edges = np.concatenate([[0.0], np.cumsum(shares / shares.sum())])
    u = min(max(float(u), 0.0), float(np.nextafter(1.0, 0.0)))
    i = min(int(np.searchsorted(edges, u, side="right")) - 1, len(palette) - 1)
    return i, (u - edges[i]) / max(edges[i + 1] - edges[i], 1e-12)


def clothing_colour(u: float, palette: tuple[PaletteColour, ...] = TOP_PALETTE) -> HSV:
    """The colour of ``palette`` that the uniform number ``u`` falls on, with its shade.

    Parameters
    ----------
    u : float
        A uniform draw in ``[0, 1)``.
    palette : tuple of PaletteColour
        Colours and their shares (normalised here).

    Returns
    -------
    tuple of float
        ``(hue, saturation, value)``: the palette colour whose cumulative share interval
        holds ``u``, shaded by where in that interval ``u`` lies.
    """
    i, rest = _pick(u, palette)
    # three roughly independent shade digits from the one remainder
    shade = (rest, (rest * 7.0) % 1.0, (rest * 13.0) % 1.0)
    hue, saturation, value = palette[i].hsv
    value *= 1.0 + _VALUE_SPREAD * (shade[0] - 0.5)
    hue = (hue + _HUE_SPREAD_DEG * (shade[1] - 0.5)) % 360.0
    saturation *= 1.0 + _SATURATION_SPREAD * (shade[2] - 0.5)
    return (float(hue), float(np.clip(saturation, 0.0, 1.0)), float(np.clip(value, 0.0, 1.0)))


def palette_name(u: float, palette: tuple[PaletteColour, ...] = TOP_PALETTE) -> str:
    """Name of the palette colour that ``u`` falls on (see :func:`clothing_colour`)."""
    return palette[_pick(u, palette)[0]].name
