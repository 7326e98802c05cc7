"""Exact handling of late batches: snapshots of recent steps, rewound and replayed.

A batch captured before the tracker's current time arrived late (network jitter, a
slower sensor). Applying it on top of later steps would use it out of order; dropping
it would lose a real observation. :class:`ReplayHistory` keeps, for each in-order step
of the last ``max_lateness_s``, the tracker's state before the step and the batch it
applied. A late batch rewinds to the last state taken before its capture time; the
tracker then re-applies it and every later batch in capture order, and ends exactly
where it would have, had the late batch arrived on time.

What the history stores is opaque to it: the tracker decides what a snapshot holds
(its track table, clock, id counter, and the state of every stateful role).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

from openptrack_py.messages.detection import DetectionBatch

S = TypeVar("S")


@dataclass(frozen=True)
class Rewind(Generic[S]):
    """Where to go back to for a late batch, and what to replay from there.

    Parameters
    ----------
    state : object
        The snapshot to restore.
    batches : list of DetectionBatch
        The late batch and every batch applied since the snapshot, in capture order.
    """

    state: S
    batches: list[DetectionBatch]


class ReplayHistory(Generic[S]):
    """Snapshots of the last steps, for replaying late batches.

    Parameters
    ----------
    max_lateness_s : float
        How far back snapshots reach; a batch later than that cannot be replayed.
    max_replay_steps : int
        A late batch that would replay more steps than this is refused.
    """

    def __init__(self, max_lateness_s: float, max_replay_steps: int) -> None:
        self.max_lateness_s = max_lateness_s
        self.max_replay_steps = max_replay_steps
        # (capture stamp, state before the step, batch) of recent in-order steps
        self._steps: deque[tuple[float, S, DetectionBatch]] = deque()

    def __len__(self) -> int:
        return len(self._steps)

    def remember(self, stamp: float, state: S, batch: DetectionBatch) -> None:
        """Record an in-order step: the state before it and the batch it applies."""
        self._steps.append((stamp, state, batch))
        while self._steps and self._steps[0][0] < stamp - self.max_lateness_s:
            self._steps.popleft()

    def rewind(
        self, batch: DetectionBatch, now: float, state_time: Callable[[S], float | None]
    ) -> Rewind[S] | None:
        """Take back the steps after ``batch``'s capture; ``None`` when it cannot be.

        Parameters
        ----------
        batch : DetectionBatch
            The late batch.
        now : float
            The tracker's current time.
        state_time : callable
            The clock of a stored state (``None`` before the first step).
        """
        steps = self._steps
        later = [i for i, (stamp, _, _) in enumerate(steps) if stamp > batch.stamp]
        first = later[0] if later else len(steps)
        if (
            now - batch.stamp > self.max_lateness_s
            or first >= len(steps)
            or len(steps) - first > self.max_replay_steps
        ):
            return None
        before = state_time(steps[first][1])
        if before is not None and before > batch.stamp:
            return None
        state = steps[first][1]
        replay = [steps[i][2] for i in range(first, len(steps))]
        for _ in range(len(steps) - first):
            steps.pop()
        return Rewind(state, sorted([batch, *replay], key=lambda b: b.stamp))
