"""Colour signatures as a simulated sensor measures them.

The detection-level sensor model (:mod:`~openptrack_py.sim.sensors`) gives each
detection a signature in the real detector's layout
(:mod:`openptrack_py.detection.appearance`: :data:`APPEARANCE_BINS` hue bins, then dark,
grey and light), binned by the detector's own rule from the person's clothes as this
sensor sees them:

* the body's pixels: top 55 %, bottom 35 %, skin 7 %, hair 3 %, each spread over the
  shading of a standing body (mostly ambient light, as the renderer lights it) and a few
  degrees of hue;
* a fixed **colour cast** per sensor (:class:`ColourCast`: white balance and exposure,
  drawn once from the sensor's appearance generator);
* **light** that varies per person and frame (hue, saturation and value jitter);
* **occlusion**: when someone nearer the sensor overlaps the person's image box, their
  colours take the overlapping share of the box; someone behind bleeds in a quarter of
  that (segmentation is never clean); at most 80 % in all;
* per-bin segmentation noise. False detections get random signatures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from openptrack_py.detection.appearance import normalise_signatures, signature_bins
from openptrack_py.sim.clothing import HAIR, SKIN
from openptrack_py.sim.people import Snapshot
from openptrack_py.sim.sensor_spec import APPEARANCE_BINS, APPEARANCE_LENGTH

# Share of a person's visible pixels per part: top, bottom, skin, hair.
_PART_SHARES = np.array([0.55, 0.35, 0.07, 0.03])
# Spread of one garment's pixels: shading (value factors) and hue offsets, with weights.
# (Most of a standing body is lit by ambient light only: the renderer's 0.8.)
_SHADE = np.array([0.75, 0.85, 1.0, 1.1])
_SHADE_WEIGHT = np.array([0.35, 0.35, 0.2, 0.1])
_HUE_OFFSET_DEG = np.array([-8.0, 0.0, 8.0])
_HUE_WEIGHT = np.array([0.2, 0.6, 0.2])
_WEIGHT = (_PART_SHARES[:, None, None] * _SHADE_WEIGHT[:, None] * _HUE_WEIGHT).reshape(-1)
"""Share of each (part, shade, hue offset) sample: sums to one."""
_BEHIND_BLEED = 0.25
"""Weight of a person behind, relative to one in front, in a detection's colours."""
_MAX_MIX = 0.8
"""Largest share of a detection's colours that neighbours may take."""


@dataclass(frozen=True)
class ColourCast:
    """A sensor's fixed colour rendition: white balance and exposure.

    Parameters
    ----------
    hue_shift_deg : float
        Added to every hue, degrees.
    saturation_scale, value_scale : float
        Multiply saturation and value.
    """

    hue_shift_deg: float = 0.0
    saturation_scale: float = 1.0
    value_scale: float = 1.0

    @classmethod
    def draw(cls, rng: np.random.Generator) -> ColourCast:
        """A random cast: hue within a few degrees, saturation +-15 %, exposure +-20 %."""
        return cls(
            hue_shift_deg=float(np.clip(rng.normal(0.0, 3.0), -8.0, 8.0)),
            saturation_scale=float(rng.uniform(0.85, 1.15)),
            value_scale=float(rng.uniform(0.8, 1.2)),
        )


class SignatureModel:
    """One sensor's colour signatures of what it detects.

    Parameters
    ----------
    camera_from_world : ndarray
        ``4 x 4`` transform from the world to the sensor's optical frame.
    rng : numpy.random.Generator
        The sensor's appearance generator: the cast is its first draw, then light,
        segmentation noise and false detections' signatures, frame by frame.
    """

    def __init__(self, camera_from_world: np.ndarray, rng: np.random.Generator) -> None:
        self.camera_from_world = camera_from_world
        self.rng = rng
        self.cast = ColourCast.draw(rng)

    def measure(self, snap: Snapshot, rows: np.ndarray, boxes: np.ndarray | None) -> np.ndarray:
        """Signatures of the detections of ``snap``'s ``rows`` (-1: no person behind it).

        Parameters
        ----------
        snap : Snapshot
            Everyone in the world now.
        rows : ndarray
            Per detection, the row of ``snap`` it shows, or -1 for a false detection.
        boxes : ndarray or None
            ``(len(snap), 4)`` image boxes ``(u, v, width, height)`` of everyone, in the
            sensor's image; None when ``snap`` holds fewer than two people.

        Returns
        -------
        ndarray
            ``(len(rows), APPEARANCE_LENGTH)`` integer signatures summing to about 255.
        """
        rng = self.rng
        n = len(rows)
        hist = np.full((n, APPEARANCE_LENGTH), 0.003)  # background the segmentation keeps
        real = np.flatnonzero(rows >= 0)
        if len(real):
            mix = self._neighbour_weights(snap, rows[real], boxes)
            seen = np.union1d(rows[real], np.flatnonzero(mix.any(axis=0)))
            people = np.zeros((len(snap), APPEARANCE_LENGTH))
            people[seen] = self._colour_mass(snap, seen, rng)
            own = 1.0 - mix.sum(axis=1)
            hist[real] += own[:, None] * people[rows[real]] + mix @ people
        fake = np.flatnonzero(rows < 0)
        hist[fake] += rng.random((len(fake), APPEARANCE_LENGTH)) ** 2
        hist *= rng.gamma(20.0, 1 / 20.0, hist.shape)  # segmentation noise per bin
        return normalise_signatures(hist).astype(int)

    def _colour_mass(
        self, snap: Snapshot, rows: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray:
        """Colour distribution of the people in ``rows`` of ``snap`` as this sensor sees them.

        Returns
        -------
        ndarray
            ``(len(rows), APPEARANCE_LENGTH)``, each row summing to one: every part's
            colour under the sensor's cast and this frame's light, spread over shading
            and hue.
        """
        n = len(rows)
        top, bottom = snap.clothing()
        parts = np.empty((n, 4, 3))
        parts[:, 0], parts[:, 1], parts[:, 2], parts[:, 3] = top[rows], bottom[rows], SKIN, HAIR
        cast = self.cast
        light_h = rng.normal(0.0, 2.0, n)
        light_s = rng.lognormal(0.0, 0.05, n)
        light_v = rng.lognormal(0.0, 0.08, n)
        hue = parts[..., 0] + cast.hue_shift_deg + light_h[:, None]  # (n, parts)
        sat = np.clip(parts[..., 1] * cast.saturation_scale * light_s[:, None], 0.0, 1.0)
        val = parts[..., 2] * cast.value_scale * light_v[:, None]
        bins = signature_bins(  # (n, parts, shade, hue offset)
            hue[:, :, None, None] + _HUE_OFFSET_DEG,
            sat[:, :, None, None],
            np.minimum(val[:, :, None, None] * _SHADE[:, None], 1.0),
            bins=APPEARANCE_BINS,
        )
        keys = (np.arange(n)[:, None] * APPEARANCE_LENGTH + bins.reshape(n, -1)).reshape(-1)
        mass = np.bincount(keys, np.tile(_WEIGHT, n), minlength=n * APPEARANCE_LENGTH)
        return mass.reshape(n, APPEARANCE_LENGTH)

    def _neighbour_weights(
        self, snap: Snapshot, rows: np.ndarray, boxes: np.ndarray | None
    ) -> np.ndarray:
        """``(len(rows), n)`` share of each detection's colours from each other person.

        A person nearer the sensor whose image box overlaps the detection's lends the
        overlapping fraction of the box; one further away a quarter of that. At most
        :data:`_MAX_MIX` in all.
        """
        n = len(snap)
        if n < 2 or boxes is None:
            return np.zeros((len(rows), n))
        centre = np.column_stack([snap.pos, 0.5 * snap.height])
        depth = (centre @ self.camera_from_world[:3, :3].T + self.camera_from_world[:3, 3])[:, 2]
        box = np.asarray(boxes, dtype=float)
        u0, v0 = box[:, 0], box[:, 1]
        u1, v1 = u0 + box[:, 2], v0 + box[:, 3]
        area = np.maximum(box[:, 2] * box[:, 3], 1.0)
        wide = np.maximum(0.0, np.minimum(u1[rows, None], u1) - np.maximum(u0[rows, None], u0))
        tall = np.maximum(0.0, np.minimum(v1[rows, None], v1) - np.maximum(v0[rows, None], v0))
        overlap = wide * tall / area[rows, None]
        nearer = depth[None, :] < depth[rows, None]
        out = np.where(nearer, overlap, _BEHIND_BLEED * overlap)
        out[:, depth <= 0.3] = 0.0  # behind the camera: no box
        out[np.arange(len(rows)), rows] = 0.0
        total = out.sum(axis=1, keepdims=True)
        return out * np.minimum(1.0, _MAX_MIX / np.maximum(total, 1e-12))
