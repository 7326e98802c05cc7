"""One pass over a stream of frames: every person, every pair, every place.

:func:`analyze` feeds each :class:`~openptrack_py.analytics.frames.PeopleFrame` to the
tallies (:mod:`~openptrack_py.analytics.people`, :mod:`~openptrack_py.analytics.pairs`,
:mod:`~openptrack_py.analytics.places`); each frame counts for the time to the next one,
up to ``max_gap_s``. Memory does not grow with the recording's length, only with the
number of different people (ids) and places. The result holds every figure, as tables
(:meth:`Analysis.tables`) and for the report (:mod:`~openptrack_py.analytics.report`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from openptrack_py.analytics.frames import PeopleFrame
from openptrack_py.analytics.pairs import PairSummary, PairTally
from openptrack_py.analytics.people import PersonSummary, PersonTally
from openptrack_py.analytics.places import DoorSummary, PlaceTally, ZoneSummary
from openptrack_py.config import DoorConfig, ZoneConfig

__all__ = ["Analysis", "analyze"]


@dataclass
class Analysis:
    """Every figure of one recording (or stream of frames).

    Parameters
    ----------
    start, end : float
        First and last frame time, UNIX seconds.
    frames : int
        Frames read.
    people : dict of int to PersonSummary
        Per person.
    pairs : dict of (int, int) to PairSummary
        Per pair seen together.
    zones : list of ZoneSummary
    doors : list of DoorSummary
    heatmap : ndarray
        Person-seconds per cell (rows along y).
    heatmap_origin : (float, float)
        The grid's lower-left corner, metres.
    cell_m : float
        Heatmap cell side.
    zone_polygons : dict of str to ndarray
        The zones' polygons (for plots).
    door_segments : dict of str to ndarray
        The doors' ends (for plots).
    pair_frames_skipped : int
        Frames with too many people for pairs
        (:class:`~openptrack_py.analytics.pairs.PairTally`).
    """

    start: float
    end: float
    frames: int
    people: dict[int, PersonSummary]
    pairs: dict[tuple[int, int], PairSummary]
    zones: list[ZoneSummary]
    doors: list[DoorSummary]
    heatmap: np.ndarray
    heatmap_origin: tuple[float, float]
    cell_m: float
    zone_polygons: dict[str, np.ndarray]
    door_segments: dict[str, np.ndarray]
    pair_frames_skipped: int = 0

    @property
    def duration_s(self) -> float:
        """Time from the first frame to the last, seconds."""
        return max(self.end - self.start, 0.0)

    def names(self) -> dict[int, str]:
        """The roster's names of the people who have one."""
        return {k: p.name for k, p in self.people.items() if p.name}

    def label(self, key: int) -> str:
        """``name (key)`` or the key."""
        name = self.people[key].name if key in self.people else None
        return f"{name} ({key})" if name else str(key)

    def tables(self) -> dict[str, list[dict[str, object]]]:
        """Every table: ``people``, ``pairs``, ``zones``, ``dwell``, ``doors``."""
        names = self.names()
        pairs = sorted(self.pairs.values(), key=lambda p: (p.a, p.b))
        dwell = [
            {"zone": z.name, "person": k, "name": names.get(k, ""), "dwell_s": round(v, 1)}
            for z in self.zones
            for k, v in sorted(z.dwell_s.items())
        ]
        return {
            "people": [p.row() for _, p in sorted(self.people.items())],
            "pairs": [p.row(names) for p in pairs],
            "zones": [z.row() for z in self.zones],
            "dwell": dwell,
            "doors": [d.row() for d in self.doors],
        }


def analyze(
    frames: Iterable[PeopleFrame],
    *,
    zones: Sequence[ZoneConfig] = (),
    doors: Sequence[DoorConfig] = (),
    max_gap_s: float = 1.0,
    cell_m: float = 0.25,
    min_seen_s: float = 1.0,
) -> Analysis:
    """Every figure of a stream of frames.

    Parameters
    ----------
    frames : iterable of PeopleFrame
        In time order.
    zones, doors : sequence
        Places to report on (the network file's).
    max_gap_s : float
        Longest time one frame counts for (a gap in the stream is not time seen).
    cell_m : float
        Cell side of the heatmap and of the density areas, metres.
    min_seen_s : float
        People seen for less than this are left out of the people and pairs (a tracker's
        brief false tracks).
    """
    people: dict[int, PersonTally] = {}
    pairs = PairTally()
    places = PlaceTally(zones, doors, cell_m, max_gap_s)
    start = end = None
    count = 0
    previous: PeopleFrame | None = None
    for frame in frames:
        count += 1
        if previous is not None:
            _add(previous, min(frame.t - previous.t, max_gap_s), people, pairs, places, cell_m)
        previous = frame
        start = frame.t if start is None else start
        end = frame.t
    if previous is not None:
        _add(previous, 0.0, people, pairs, places, cell_m)
    summaries = {k: p.summary() for k, p in people.items() if p.seen_s >= min_seen_s}
    kept_pairs = {
        key: pair for key, pair in pairs.summaries().items()
        if key[0] in summaries and key[1] in summaries
    }  # fmt: skip
    heatmap, origin = places.heatmap()
    return Analysis(
        start=start or 0.0,
        end=end or 0.0,
        frames=count,
        people=summaries,
        pairs=kept_pairs,
        zones=places.zone_summaries(),
        doors=places.door_summaries(),
        heatmap=heatmap,
        heatmap_origin=origin,
        cell_m=cell_m,
        zone_polygons={z.name: np.array(z.polygon, dtype=float) for z in zones},
        door_segments={d.name: np.array([d.a, d.b], dtype=float) for d in doors},
        pair_frames_skipped=pairs.skipped_frames,
    )


def _add(
    frame: PeopleFrame,
    dt: float,
    people: dict[int, PersonTally],
    pairs: PairTally,
    places: PlaceTally,
    cell_m: float,
) -> None:
    for key, (x, y) in frame.positions.items():
        tally = people.get(key)
        if tally is None:
            tally = people[key] = PersonTally(key, cell_m=cell_m)
        tally.add(frame.t, x, y, dt, frame.names.get(key))
    pairs.add(frame.t, frame.positions, dt)
    places.add(frame.t, frame.positions, dt)
