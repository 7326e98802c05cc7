"""Tiny stubs of every tracker role, so a test can compose a tracker from parts it controls.

Each stub implements only its role's protocol (:mod:`openptrack_py.tracking.base`) and
nothing else: a tracker built from them proves that the tracker reads no field of its
parts beyond their interface. The sensor and identity roles are the project's own that
learn nothing (:class:`StaticSensorModel`, :class:`NullIdentity`).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np
import pytest

from openptrack_py.tracking import (
    DetectionArrays,
    NullIdentity,
    StaticSensorModel,
    Tracker,
    TrackerParams,
    TrackTable,
)


class StillMotion:
    """People do not move; a little process noise keeps the filter responsive."""

    def fx(self, sigmas: np.ndarray, dt: np.ndarray) -> np.ndarray:
        return sigmas.copy()

    def noise(self, dt: np.ndarray) -> np.ndarray:
        return np.broadcast_to(np.eye(4) * 1e-3, (len(np.atleast_1d(dt)), 4, 4)).copy()


class FixedNoisePosition:
    """A detection measures the floor position with a fixed 5 cm noise."""

    dim = 2
    sigma_m = 0.05

    def hx(self, sigmas: np.ndarray) -> np.ndarray:
        return sigmas[..., 0:2]

    def position_noise(self, distance: np.ndarray) -> np.ndarray:
        return np.broadcast_to(np.eye(2) * self.sigma_m**2, (len(distance), 2, 2)).copy()

    def pair_measurements(
        self, dets: DetectionArrays, table: TrackTable, t: float
    ) -> tuple[np.ndarray, np.ndarray]:
        n = len(table)
        z = np.broadcast_to(dets.xy, (n, *dets.xy.shape))
        r = np.broadcast_to(self.position_noise(dets.distance), (n, len(dets), 2, 2))
        return z, r


class ThresholdGate:
    """Admits squared distances up to 9."""

    dof = 2
    threshold = 9.0

    def gate(self, d2: np.ndarray) -> np.ndarray:
        return d2 <= self.threshold


class GreedyAssociator:
    """Cheapest admissible pair first, one-to-one."""

    def associate(self, cost: np.ndarray, allowed: np.ndarray) -> list[tuple[int, int]]:
        pairs: list[tuple[int, int]] = []
        used_rows: set[int] = set()
        used_cols: set[int] = set()
        for flat in np.argsort(np.where(allowed, cost, np.inf), axis=None):
            i, j = np.unravel_index(flat, cost.shape)
            if not allowed[i, j]:
                break
            if i not in used_rows and j not in used_cols:
                pairs.append((int(i), int(j)))
                used_rows.add(int(i))
                used_cols.add(int(j))
        return pairs


class EveryOrphanInitiator:
    """Every detection no track explains starts a track; two hits confirm it."""

    def initiate(
        self,
        dets: DetectionArrays,
        assigned: np.ndarray,
        d2: np.ndarray,
        table: TrackTable | None = None,
    ) -> np.ndarray:
        in_any_gate = (d2 <= ThresholdGate.threshold).any(axis=0) if len(d2) else False
        return np.flatnonzero(~assigned & ~in_any_gate)

    def confirm(
        self, table: TrackTable, t: float, continuing: np.ndarray | None = None
    ) -> np.ndarray:
        return table.confirmed | (table.hits >= 2)


class UnseenDeleter:
    """A track unseen for a second ends."""

    def delete(self, table: TrackTable, t: float) -> np.ndarray:
        return t - table.last_seen > 1.0


class NeverMerge:
    """No two tracks are ever one person."""

    def observe(
        self,
        table: TrackTable,
        rows: np.ndarray,
        t: float,
        noise: np.ndarray | None = None,
        sensor: int = 0,
        apart: np.ndarray | None = None,
    ) -> None:
        pass

    def merge(self, table: TrackTable, t: float) -> list[tuple[int, int]]:
        return []

    def reattach(
        self, table: TrackTable, t: float, new: np.ndarray, lost_after_s: float
    ) -> list[tuple[int, int]]:
        return []

    def continuations(self, table: TrackTable, t: float, lost_after_s: float) -> np.ndarray:
        return np.zeros(len(table), dtype=bool)

    def distinct_rows(self, table: TrackTable, t: float) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)


@dataclass
class ForgetfulIdentity(NullIdentity):
    """An identity role that counts each track's observations and names it by them.

    It keeps that state to itself (no ``snapshot``/``restore``): a late-batch replay
    cannot restore it, so it counts replayed observations twice.
    """

    counts: dict[int, int] = field(default_factory=dict)

    def observe(
        self,
        table: TrackTable,
        rows: np.ndarray,
        cols: np.ndarray,
        dets: DetectionArrays,
        t: float,
        certain: np.ndarray | None = None,
    ) -> None:
        for ident in table.ids[rows].tolist():
            self.counts[ident] = self.counts.get(ident, 0) + 1

    def started(
        self, table: TrackTable, rows: np.ndarray, dets: DetectionArrays, t: float
    ) -> None:
        for ident in table.ids[rows].tolist():
            self.counts[ident] = 1

    def ended(
        self, table: TrackTable, rows: np.ndarray, t: float, reason: str = "deleted"
    ) -> None:
        for ident in table.ids[rows].tolist():
            self.counts.pop(ident, None)

    def labels(self, ids: np.ndarray) -> tuple[list[int], list[str]]:
        ids = ids.tolist()
        return [i + 10_000 for i in ids], [f"seen{self.counts.get(i, 0)}" for i in ids]


class CountingIdentity(ForgetfulIdentity):
    """The same role with its state where the tracker's replay restores it."""

    def snapshot(self) -> dict[int, int]:
        return copy.deepcopy(self.counts)

    def restore(self, state: dict[int, int]) -> None:
        self.counts = copy.deepcopy(state)


def stub_tracker(identity: object | None = None, **kw: object) -> Tracker:
    """A tracker made only of stub roles."""
    return Tracker(
        StillMotion(),
        FixedNoisePosition(),
        ThresholdGate(),
        GreedyAssociator(),
        EveryOrphanInitiator(),
        UnseenDeleter(),
        StaticSensorModel(),
        NeverMerge(),
        identity,  # type: ignore[arg-type]
        TrackerParams(**kw),  # type: ignore[arg-type]
    )


@pytest.fixture
def stub_roles() -> dict[str, object]:
    """One fresh stub per role, by role name."""
    return {
        "motion": StillMotion(),
        "measurement": FixedNoisePosition(),
        "gater": ThresholdGate(),
        "associator": GreedyAssociator(),
        "initiator": EveryOrphanInitiator(),
        "deleter": UnseenDeleter(),
        "sensors": StaticSensorModel(),
        "merger": NeverMerge(),
    }
