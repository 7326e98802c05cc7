"""The tracker's state on disk, so that a restart neither loses people nor reuses ids.

OpenPTrack's tracker started again from id 1 after a crash, so creative apps saw old ids
on new people. :class:`CheckpointStore` keeps, in one file written atomically (a
temporary file renamed over the old one, readable by its owner only):

* the whole tracker state the late-batch replay restores (the track table, the clock,
  the id counter, and the state of every role that keeps one: learned sensor noise and
  alignment, merging timers, identity), and which sensor each of the table's per-sensor
  columns belongs to (a restarted tracker numbers its sensors as they come);
* an **id reservation**: ids up to ``reserved_id`` may have been given out. It is
  written before the tracker passes it (:data:`ID_BLOCK` at a time), so after a crash
  between two checkpoints a restarted tracker starts above every id it could have
  published.

:func:`resume_ids` and :func:`resume_tracks` put a checkpoint back into a new tracker. The
tracks are resumed when the checkpoint is recent (the tracker node's
``resume_within_s``), at the first batch after the restart: the time the tracker was
down does not count as time unseen (their keepalive and confirmation clocks move on by
the gap), their velocity is forgotten and their position uncertainty grows by what a
person can walk in that gap, so the first detections of each person find their old track
again. An older
checkpoint resumes only the id counter.

The file is a pickle of the tracker's own state, written and read by the tracker alone
in its own directory; it is never read from anywhere else.
"""

from __future__ import annotations

import logging
import os
import pickle
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from openptrack_py.tracking.state import TrackTable

log = logging.getLogger(__name__)

FORMAT = 1
"""Version of the checkpoint file's contents."""
ID_BLOCK = 1000
"""Ids reserved ahead of the id counter in each checkpoint."""
RESUMED_SPEED_MPS = 1.0
"""How fast a resumed track's person may have walked while the tracker was down."""
RESUMED_MAX_SIGMA_M = 2.0
"""Largest position uncertainty added to a resumed track: wider, a track could not claim
a detection over the sensor's clutter (and a person who walked farther in a few seconds
is found by re-attachment instead)."""


@dataclass(frozen=True)
class Checkpoint:
    """A tracker's state at one moment.

    Parameters
    ----------
    saved_at : float
        Wall-clock time of writing, UNIX seconds.
    time : float or None
        The tracker's clock (capture time of its last batch).
    max_id : int
        The id counter.
    reserved_id : int
        Every id given out is at most this.
    max_published_id : int
        Highest id published.
    seq : int
        Output sequence number.
    frame_id : str
        Frame tracked.
    table : TrackTable
        Every track.
    roles : tuple
        Each stateful role's snapshot (``None`` for the others), in role order.
    sensors : tuple of str
        The sensors in the order of the table's per-sensor columns (none in a checkpoint
        written before it was kept).
    """

    saved_at: float
    time: float | None
    max_id: int
    reserved_id: int
    max_published_id: int
    seq: int
    frame_id: str
    table: TrackTable
    roles: tuple[Any, ...]
    sensors: tuple[str, ...] = ()


class CheckpointStore:
    """One tracker's checkpoint file.

    Parameters
    ----------
    path : Path
        The file (its directory is created, readable by its owner only).
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path).expanduser()
        self.reserved_id = 0

    def load(self) -> Checkpoint | None:
        """The checkpoint on disk, or ``None`` (none yet, or unreadable: logged)."""
        try:
            data = self.path.read_bytes()
        except FileNotFoundError:
            return None
        except OSError as exc:
            log.warning("cannot read the tracker checkpoint %s: %s", self.path, exc)
            return None
        try:
            version, ckpt = pickle.loads(data)
            if version != FORMAT or not isinstance(ckpt, Checkpoint):
                raise ValueError(f"format {version!r}")
        except Exception as exc:
            log.warning("ignoring the unreadable tracker checkpoint %s: %s", self.path, exc)
            return None
        self.reserved_id = max(self.reserved_id, ckpt.reserved_id)
        return ckpt

    def save(self, tracker: Any) -> None:
        """Write ``tracker``'s state, reserving ids ahead of its counter."""
        self.reserved_id = max(self.reserved_id, tracker.max_id + ID_BLOCK)
        snapshot = tracker.snapshot()
        ckpt = Checkpoint(
            saved_at=time.time(),
            time=snapshot.time,
            max_id=snapshot.max_id,
            reserved_id=self.reserved_id,
            max_published_id=tracker.max_published_id,
            seq=tracker.seq,
            frame_id=tracker.frame_id,
            table=snapshot.table,
            roles=snapshot.roles,
            sensors=tuple(tracker.sensor_index),
        )
        self.path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        fd, tmp = tempfile.mkstemp(prefix=".tracker-", dir=self.path.parent)
        try:
            with os.fdopen(fd, "wb") as f:
                pickle.dump((FORMAT, ckpt), f, protocol=pickle.HIGHEST_PROTOCOL)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    def due(self, tracker: Any) -> bool:
        """Whether the tracker is about to give out ids beyond the last reservation."""
        return tracker.max_id > self.reserved_id - ID_BLOCK // 2


def resume_ids(tracker: Any, ckpt: Checkpoint) -> None:
    """Continue the id counter above every id ``ckpt`` may have given out."""
    tracker.max_id = max(tracker.max_id, ckpt.reserved_id)
    tracker.max_published_id = max(tracker.max_published_id, ckpt.max_published_id)
    tracker.seq = max(tracker.seq, ckpt.seq)


def resume_tracks(tracker: Any, ckpt: Checkpoint, now: float) -> int:
    """Put ``ckpt``'s tracks back into ``tracker`` as of tracker time ``now``.

    ``now`` is the capture time of the first batch after the restart: the gap since the
    checkpoint is not counted as time unseen, and each track's position uncertainty
    grows by what a person walks in it (its velocity is forgotten). Returns how many
    tracks were resumed.
    """
    if ckpt.time is None or not len(ckpt.table):
        return 0
    gap = max(now - ckpt.time, 0.0)
    table = ckpt.table.copy()
    for name in ("first_seen", "last_seen", "multi_t", "hist_t", "sensor_hit_t"):
        setattr(table, name, getattr(table, name) + gap)
    walked = min(RESUMED_SPEED_MPS * gap, RESUMED_MAX_SIGMA_M) ** 2
    table.cov[:, 0, 0] += walked
    table.cov[:, 1, 1] += walked
    table.cov[:, 0:2, 2:4] = 0.0
    table.cov[:, 2:4, 0:2] = 0.0
    table.cov[:, 2:4, 2:4] = np.eye(2) * max(float(table.cov[:, 2, 2].max()), 1.0)
    table.x[:, 2:4] = 0.0
    if not tracker.sensor_index:  # the resumed tracks' columns keep their sensors
        tracker.sensor_index.update({s: i for i, s in enumerate(ckpt.sensors)})
    tracker.restore_state(table, ckpt.time + gap, ckpt.roles)
    return len(table)
