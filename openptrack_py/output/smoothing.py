"""OpenPTrack's moving-average smoother, corrected.

Per track, a window of the last ``window_size`` positions no older than
``position_lifetime_s``; one output frame per call of :meth:`MovingAverageSmoother.frame`
(the output node calls it at a fixed rate). What differs from OpenPTrack's
``moving_average_filter``:

* only *measured* positions (tracks marked ``VISIBLE`` in that step) enter the average;
  positions the tracker predicted while it did not see the person do not;
* a track leaves the output ``track_lifetime_s`` after its last measured position (in
  OpenPTrack a track seen only while not visible vanished at once, and frozen positions
  were averaged in);
* every time is the output node's own receive time, so the sensors' and the tracker's
  clocks do not matter.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field, replace

from openptrack_py.messages.track import Track, TrackBatch, Visibility


@dataclass
class _TrackWindow:
    positions: deque[tuple[float, float, float]]  # (receive time, x, y)
    last: Track
    last_measured: float


@dataclass
class MovingAverageSmoother:
    """Averages each track's recent measured positions.

    Parameters
    ----------
    window_size : int
        Positions averaged per track.
    position_lifetime_s : float
        Older positions leave the window (the newest one always stays).
    track_lifetime_s : float
        A track leaves the output this long after its last measured position.

    A frame's ``alive_ids`` are exactly the ids of its tracks and ``max_id`` the highest
    id this smoother ever published, so heartbeats never list an id no frame showed.
    """

    window_size: int = 5
    position_lifetime_s: float = 0.6
    track_lifetime_s: float = 0.6
    _tracks: dict[int, _TrackWindow] = field(default_factory=dict)
    _max_id: int = 0
    _seq: int = 0

    def __post_init__(self) -> None:
        if self.window_size < 1:
            raise ValueError(
                f"MovingAverageSmoother: window_size must be >= 1, got {self.window_size}"
            )
        for name in ("position_lifetime_s", "track_lifetime_s"):
            if not getattr(self, name) > 0:
                raise ValueError(
                    f"MovingAverageSmoother: {name} must be > 0, got {getattr(self, name)}"
                )

    def push(self, batch: TrackBatch, now: float) -> None:
        """Take one tracker message received at ``now`` (local clock)."""
        for track in batch.tracks:
            window = self._tracks.get(track.id)
            measured = track.visibility == Visibility.VISIBLE
            if window is None:
                if not measured:
                    continue  # never seen by this smoother: nothing to average yet
                window = _TrackWindow(deque(maxlen=self.window_size), track, now)
                self._tracks[track.id] = window
            window.last = track
            if measured:
                window.positions.append((now, track.x, track.y))
                window.last_measured = now

    def frame(self, now: float) -> TrackBatch:
        """The smoothed tracks at ``now``."""
        self._seq += 1
        out = []
        for ident in list(self._tracks):
            window = self._tracks[ident]
            if now - window.last_measured >= self.track_lifetime_s:
                del self._tracks[ident]
                continue
            positions = window.positions
            while len(positions) > 1 and positions[0][0] < now - self.position_lifetime_s:
                positions.popleft()
            n = len(positions)
            x = sum(p[1] for p in positions) / n
            y = sum(p[2] for p in positions) / n
            out.append(replace(window.last, x=x, y=y))
        out.sort(key=lambda t: t.id)
        ids = tuple(t.id for t in out)
        self._max_id = max(self._max_id, *ids, 0)
        return TrackBatch(
            stamp=now,
            seq=self._seq,
            frame_id="world",
            tracks=tuple(out),
            alive_ids=ids,
            max_id=self._max_id,
        )
