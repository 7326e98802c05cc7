"""Who the simulated people are, and everyone's state at one instant.

:class:`PersonSpec` is a person's build, pace and clothes; :func:`random_person` draws
one, dressed from the realistic palettes of :mod:`~openptrack_py.sim.clothing`.
:class:`Snapshot` is everyone's state at one instant, as the world
(:mod:`~openptrack_py.sim.world`) hands it to sensors and ground truth.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal

import numpy as np

from openptrack_py.sim.clothing import BOTTOM_PALETTE, HSV, TOP_PALETTE, clothing_colour

PersonKind = Literal["adult", "child"]


@dataclass(frozen=True)
class PersonSpec:
    """What a simulated person looks like and how fast they like to walk.

    Parameters
    ----------
    kind : {"adult", "child"}
        Adult or child.
    height : float
        Stature, metres.
    radius : float
        Body radius on the floor, metres.
    top_hue, bottom_hue : float
        Hue of the top (torso and arms) and bottom (hips and legs) clothing, degrees.
    speed : float
        Preferred walking speed, metres per second.
    top_saturation, top_value, bottom_saturation, bottom_value : float
        The rest of the clothing colours (HSV, 0-1); the defaults are the bright shades
        clothes had before they came from palettes.
    """

    kind: PersonKind
    height: float
    radius: float
    top_hue: float
    bottom_hue: float
    speed: float
    top_saturation: float = 0.7
    top_value: float = 0.8
    bottom_saturation: float = 0.6
    bottom_value: float = 0.55

    @property
    def top(self) -> HSV:
        """Top clothing colour ``(hue, saturation, value)``."""
        return (self.top_hue, self.top_saturation, self.top_value)

    @property
    def bottom(self) -> HSV:
        """Bottom clothing colour ``(hue, saturation, value)``."""
        return (self.bottom_hue, self.bottom_saturation, self.bottom_value)

    def wearing(self, top: HSV, bottom: HSV) -> PersonSpec:
        """The same person in other clothes (HSV colours)."""
        return dataclasses.replace(
            self,
            top_hue=float(top[0]),
            top_saturation=float(top[1]),
            top_value=float(top[2]),
            bottom_hue=float(bottom[0]),
            bottom_saturation=float(bottom[1]),
            bottom_value=float(bottom[2]),
        )


def random_person(rng: np.random.Generator, kind: PersonKind = "adult") -> PersonSpec:
    """Draw a person: adults 1.55-1.95 m, children 0.8-1.2 m, clothes from the palettes.

    Top and bottom take one uniform draw each, which
    :func:`~openptrack_py.sim.clothing.clothing_colour` maps onto the top and bottom
    palettes: the same draws as when clothes were uniformly random hues, so every draw
    after them is unchanged.
    """
    if kind == "child":
        height = float(rng.uniform(0.8, 1.2))
        radius = float(rng.uniform(0.14, 0.18))
        speed = float(rng.uniform(0.6, 1.0))
    else:
        height = float(np.clip(rng.normal(1.74, 0.09), 1.55, 1.95))
        radius = float(rng.uniform(0.2, 0.25))
        speed = float(rng.uniform(0.9, 1.4))
    top = clothing_colour(float(rng.uniform(0.0, 1.0)), TOP_PALETTE)
    bottom = clothing_colour(float(rng.uniform(0.0, 1.0)), BOTTOM_PALETTE)
    return PersonSpec(
        kind=kind,
        height=height,
        radius=radius,
        top_hue=top[0],
        bottom_hue=bottom[0],
        speed=speed,
        top_saturation=top[1],
        top_value=top[2],
        bottom_saturation=bottom[1],
        bottom_value=bottom[2],
    )


@dataclass(frozen=True)
class Snapshot:
    """Everyone's state at one instant.

    Parameters
    ----------
    t : float
        Scenario time, seconds.
    ids, kinds : ndarray
        Person id and kind per row.
    pos, vel : ndarray
        ``(n, 2)`` positions (metres) and velocities (m/s).
    height, radius : ndarray
        Stature and body radius per row.
    top_hue, bottom_hue : ndarray
        Clothing hues per row, degrees.
    top_saturation, top_value, bottom_saturation, bottom_value : ndarray, optional
        The rest of the clothing colours per row (HSV, 0-1); the :class:`PersonSpec`
        defaults when omitted.
    heading : ndarray, optional
        Direction each person faces, radians: where they last walked (a standing person
        keeps the last heading); from the velocity when omitted.
    """

    t: float
    ids: np.ndarray
    kinds: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    height: np.ndarray
    radius: np.ndarray
    top_hue: np.ndarray
    bottom_hue: np.ndarray
    top_saturation: np.ndarray | None = None
    top_value: np.ndarray | None = None
    bottom_saturation: np.ndarray | None = None
    bottom_value: np.ndarray | None = None
    heading: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.ids)

    def clothing(self) -> tuple[np.ndarray, np.ndarray]:
        """Top and bottom clothing colours, each ``(n, 3)`` HSV rows."""
        n = len(self.ids)

        def column(values: np.ndarray | None, default: float) -> np.ndarray:
            return np.full(n, default) if values is None else np.asarray(values, dtype=float)

        top = np.column_stack(
            [
                self.top_hue,
                column(self.top_saturation, PersonSpec.top_saturation),
                column(self.top_value, PersonSpec.top_value),
            ]
        )
        bottom = np.column_stack(
            [
                self.bottom_hue,
                column(self.bottom_saturation, PersonSpec.bottom_saturation),
                column(self.bottom_value, PersonSpec.bottom_value),
            ]
        )
        return top.reshape(n, 3), bottom.reshape(n, 3)

    def facing(self) -> np.ndarray:
        """``(n, 2)`` unit vectors each person faces on the floor.

        The heading when known; else the direction of motion, or (standing, no heading)
        a fixed direction per id, as the renderer turns a standing body.
        """
        if self.heading is not None:
            return np.column_stack([np.cos(self.heading), np.sin(self.heading)]).reshape(-1, 2)
        speed = np.linalg.norm(self.vel, axis=1) if len(self.ids) else np.zeros(0)
        fallback = np.column_stack([np.cos(self.ids * 2.4), np.sin(self.ids * 2.4)])
        moving = speed[:, None] > 0.05
        return np.where(moving, self.vel / np.maximum(speed, 1e-9)[:, None], fallback).reshape(
            -1, 2
        )
