"""Ground truth published by the simulator."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class PersonState:
    """The true state of one simulated person at one instant.

    Parameters
    ----------
    id : int
        Person id within the scenario (not a track id).
    x, y : float
        Position on the floor, metres, world frame.
    height : float
        Stature, metres.
    vx, vy : float
        Velocity, metres per second.
    kind : str
        ``"adult"`` or ``"child"``.
    covered : bool
        Whether the person stands inside at least one sensor's field of view and range
        (occlusion ignored): the people a tracker is expected to report.
    """

    id: int
    x: float
    y: float
    height: float
    vx: float
    vy: float
    kind: str = "adult"
    covered: bool = True


@dataclass(frozen=True, slots=True)
class GroundTruthFrame:
    """Everyone present in the simulated world at ``stamp``.

    Parameters
    ----------
    stamp : float
        True time, UNIX seconds (no sensor clock offset).
    seq : int
        Frame counter.
    people : tuple of PersonState
        Every person inside the room.
    """

    stamp: float
    seq: int
    people: tuple[PersonState, ...] = ()
