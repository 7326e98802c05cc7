"""Who was where, frame by frame: what every analysis reads.

Analyses take a stream of :class:`PeopleFrame` (a time and each person's floor
position), so they run alike on a tracker's output, on the simulator's ground truth or
on anything else. :func:`frames_from_recording` reads one from a recording, streaming:
the tracks (or the ground truth) sampled at ``rate_hz``, each person keyed by the
identity a client sees (``stable_id`` when the tracker gives one, else its id) and named
by the roster when identity is on.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from openptrack_py.messages.codec import decode_ground_truth, decode_track_batch
from openptrack_py.recordings import Recording, read_recording

__all__ = ["PeopleFrame", "frames_from_recording"]


@dataclass(frozen=True, slots=True)
class PeopleFrame:
    """Everyone's position at one time.

    Parameters
    ----------
    t : float
        Time, UNIX seconds.
    positions : dict of int to (float, float)
        Each person's floor position, metres.
    names : dict of int to str
        Names of the people who have one.
    """

    t: float
    positions: dict[int, tuple[float, float]]
    names: dict[int, str] = field(default_factory=dict)


def frames_from_recording(
    path: Path,
    *,
    source: str = "tracks",
    rate_hz: float = 10.0,
    on_progress: Callable[[float], None] | None = None,
) -> tuple[Recording, Iterator[PeopleFrame]]:
    """The recording (for its damage report) and its frames, sampled at ``rate_hz``.

    Parameters
    ----------
    path : Path
        The recording (MCAP or JSON lines).
    source : {"tracks", "ground_truth"}
        Read the tracker's output or the simulator's ground truth.
    rate_hz : float
        Frames per second kept (a tracker publishes after every sensor batch).
    on_progress : callable, optional
        Called with each kept frame's time.
    """
    if source not in ("tracks", "ground_truth"):
        raise ValueError(f"analytics: source must be 'tracks' or 'ground_truth', got {source!r}")
    recording = read_recording(path)

    def frames() -> Iterator[PeopleFrame]:
        period = 1.0 / rate_hz
        next_t = -float("inf")
        for message in recording:
            if message.topic != source:
                continue
            if source == "tracks":
                batch = decode_track_batch(message.payload)
                t = batch.stamp
                if t < next_t:
                    continue
                positions = {}
                names = {}
                for track in batch.tracks:
                    key = track.client_id
                    positions[key] = (track.x, track.y)
                    if track.identity:
                        names[key] = track.identity
                frame = PeopleFrame(t, positions, names)
            else:
                truth = decode_ground_truth(message.payload)
                t = truth.stamp
                if t < next_t:
                    continue
                frame = PeopleFrame(t, {p.id: (p.x, p.y) for p in truth.people})
            next_t = t + period * 0.999
            if on_progress is not None:
                on_progress(t)
            yield frame

    return recording, frames()
