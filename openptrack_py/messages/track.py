"""Tracks published by the tracker, and the heartbeat derived from them."""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum


class Visibility(IntEnum):
    """How a track was seen in the latest step (OpenPTrack's numbering)."""

    VISIBLE = 0
    OCCLUDED = 1
    NOT_VISIBLE = 2


@dataclass(frozen=True, slots=True)
class Track:
    """The tracker's estimate of one person.

    Parameters
    ----------
    id : int
        Track id, positive, never reused within a tracker's lifetime.
    x, y, z : float
        Position in metres (``z`` is the centroid height above the floor).
    height : float
        Smoothed height of the person, metres.
    vx, vy : float
        Velocity on the floor, metres per second.
    age : float
        Seconds since the track's first detection.
    confidence : float
        Track confidence in ``[0, 1]``.
    visibility : Visibility
        Whether the latest step saw the person.
    confirmed : bool
        ``False`` while the track is still tentative.
    stable_id : int, optional
        Identity that survives track breaks (re-identification).
    identity : str, optional
        Name of a registered person.
    """

    id: int
    x: float
    y: float
    z: float
    height: float
    vx: float
    vy: float
    age: float
    confidence: float
    visibility: Visibility = Visibility.VISIBLE
    confirmed: bool = True
    stable_id: int | None = None
    identity: str | None = None

    @property
    def client_id(self) -> int:
        """The identity a client keys on: ``stable_id`` when given, else ``id``.

        A re-identifying tracker is judged by the identity it publishes as stable.
        """
        return self.id if self.stable_id is None else self.stable_id


@dataclass(frozen=True, slots=True)
class TrackBatch:
    """The tracker's state after one step.

    Parameters
    ----------
    stamp : float
        Time the tracks refer to, UNIX seconds (the capture time of the step's batch).
    seq : int
        Step counter of the publisher.
    frame_id : str
        Frame of the positions, normally ``"world"``.
    tracks : tuple of Track
        The published tracks (confirmed ones unless the tracker is told otherwise).
    alive_ids : tuple of int
        Ids of every track the tracker holds, published or not.
    max_id : int
        Highest id ever issued (0 before the first track).
    source : (str, int, float), optional
        The detection batch this step applied: its sensor id, ``seq`` and the capture
        time the tracker used (after clock alignment); ``None`` for a step without one.
        With it a recording says exactly what the tracker took, in which order, so
        ``openptrack retrack`` can take it again.
    """

    stamp: float
    seq: int
    frame_id: str = "world"
    tracks: tuple[Track, ...] = ()
    alive_ids: tuple[int, ...] = ()
    max_id: int = 0
    source: tuple[str, int, float] | None = None


@dataclass(frozen=True, slots=True)
class Heartbeat:
    """Which track ids are alive, sent periodically even when the room is empty.

    Parameters
    ----------
    stamp : float
        Send time, UNIX seconds.
    seq : int
        Heartbeat counter of the sender.
    alive_ids : tuple of int
        Ids of every live track.
    max_id : int
        Highest id ever issued.
    """

    stamp: float
    seq: int
    alive_ids: tuple[int, ...] = ()
    max_id: int = 0
