"""What the sensors delivered: the share of the ground truth any tracker could follow.

A person behind a cabinet for ten seconds counts as a miss in every frame of it (the
scored objects are the people inside some sensor's field of view, occlusion ignored),
whatever the tracker does. So a scenario's figures have a ceiling set by the sensors,
not the tracker. :class:`SensorReach` measures it from the simulator's labels (which
person is behind each detection): a covered person-frame is **seen** when a sensor
detection of that person arrived within the last ``window_s`` seconds.

From the seen share ``s`` follow two reference figures: a tracker that follows exactly
the seen frames, each person under one identity, and misses every other scores MOTA
``s`` and IDF1 ``2s / (1 + s)``. They are not strict bounds (a track coasting through
a short gap may still be on its person), but a figure well above them is suspect and a
target above them is out of reach for every tracker.
"""

from __future__ import annotations

from dataclasses import dataclass, field

WINDOW_S = 1.0
"""A person detected this recently counts as seen (seconds)."""


@dataclass
class SensorReach:
    """Counts covered person-frames, and those a sensor detection had recently reached.

    Parameters
    ----------
    window_s : float
        How recent a detection of the person must be, seconds.
    """

    window_s: float = WINDOW_S
    covered: int = 0
    seen: int = 0
    _last: dict[int, float] = field(default_factory=dict, init=False, repr=False)

    def on_detections(self, time: float, person_ids: tuple[int, ...]) -> None:
        """A sensor frame arrived at ``time`` with these people behind its detections.

        Id 0 is clutter or a split-off part, and is ignored.
        """
        for pid in person_ids:
            if pid:
                self._last[pid] = time

    def on_truth(self, time: float, covered_ids: list[int]) -> None:
        """One scored ground-truth frame with these covered people."""
        self.covered += len(covered_ids)
        never = -float("inf")
        self.seen += sum(time - self._last.get(pid, never) <= self.window_s for pid in covered_ids)

    def share(self) -> float | None:
        """Share of covered person-frames seen; ``None`` before any was scored."""
        if not self.covered:
            return None
        return self.seen / self.covered

    def idf1(self) -> float | None:
        """IDF1 of a tracker that follows exactly the seen frames, one identity each."""
        s = self.share()
        return None if s is None else 2.0 * s / (1.0 + s)
