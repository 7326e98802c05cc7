"""Merging two confirmed tracks that follow one person, and re-attaching a lost one.

Whatever care birth takes, a person can end up with two confirmed tracks (two sensors
whose calibrations disagree at a camera boundary, a burst of outliers). Left alone, the
two share that person's detections and live forever: OpenPTrack's best-known failure.
:class:`TrackMerger` merges them, keeping the older id, when they have stayed within
``distance_m`` of each other for ``after_s``, moving alike and both detected lately (by
any sensor, whether or not its detections still keep the track alive), and they are not
known to be two people.

Two people are known apart by what the sensors saw in the last ``distinct_s``: a sensor
frame that detected both of them at once (two blobs in one frame: two people walking
side by side are not merged). But a detector also splits one person into two blobs now
and then (an arm held out, a body seen half behind a chair: OpenPTrack's users report a
person's second id beside them), and each sensor segments its own view, so a split is
one sensor's artefact while a second person is there for every sensor that sees the
place. So, with ``distinct_sensors`` 2, where two or more sensors have detected both
tracks in the last ``sees_both_s`` (they could have seen them apart), two of them must
each have seen the pair apart; where fewer have, each of them must (one alone: its word
suffices). One sensor's split then no longer keeps a person's second track alive (nor,
through :func:`~openptrack_py.tracking.blobs.keep_apart`, pushes it off the person)
where others see the person whole. The price: two people close together whom one
sensor sees apart while the others see them as one blob may be merged, and in a dense
crowd that costs more identities than the splits do; so the default, 1, takes any one
sensor's frame as proof. Where detections are noisy, association gates overlap, and
the frame that saw a person's two tracks apart may have given the second one a
neighbour's or a stray detection: told which detections were unambiguous (each alone in
its track's gate and in no other's; the tracker's ``merge_proof_unambiguous``), the
merger takes only those as proof, while every pair a frame detected together is still
kept a body's depth apart (:meth:`TrackMerger.distinct_rows`).

How close is close depends on how noisy the detections are: each sensor's errors pull
the track it feeds its own way, so two tracks of one person drift apart by about the
detections' noise, and their velocities by about the tracks' velocity uncertainty.
With a ``gate`` the merger keeps, per track, the average measurement variance of the
detections that updated it (as scaled by the sensors' learned noise,
:class:`~openptrack_py.tracking.sensor_model.OnlineSensorModel`); a pair is close within
``max(distance_m, sqrt(gate * (v_a + v_b)))``, where a detection of the person would fall
inside either track's association gate, and moves alike within
``max(max_speed_difference_mps, sqrt(gate * (w_a + w_b)))`` (``w`` the tracks' velocity
variance per axis). Sensors noisier than configured widen both; in a clean room they
stay as configured.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from openptrack_py.tracking.neighbours import close_pairs
from openptrack_py.tracking.state import TrackTable


class TrackMerger:
    """Finds pairs of confirmed tracks that are one person.

    Parameters
    ----------
    distance_m : float
        Largest distance between two tracks of one person.
    after_s : float
        How long they must stay that close (0 disables merging); apart for less than
        this does not restart the count.
    max_speed_difference_mps : float
        Largest difference of their velocities.
    distinct_s : float
        A pair detected in one sensor frame counts as seen apart by that sensor for this
        long.
    fresh_s : float
        Both tracks must have been detected this recently (by any sensor, whether or
        not the detection kept the track alive).
    reattach_speed_mps : float
        A lost track may be the person of a new track that started within
        ``distance_m + reattach_speed_mps * elapsed`` of where it was last seen (0
        disables re-attachment).
    walking_m : float
        A lost track was walking if its estimate moved this far in its last second of
        sightings; only a walking person's lost track vouches for a new one
        (:meth:`continuations`).
    gate : float or None
        Squared Mahalanobis gate (chi-square, 2 degrees of freedom) by which the
        distance and the speed difference widen with the tracks' noise; ``None`` keeps
        them as given.
    noise_rate : float
        Weight of one update in a track's average measurement variance.
    distinct_sensors : int
        How many sensors must have seen a pair apart, where that many have detected
        both tracks in the last ``sees_both_s``; where fewer have, all of them must
        (1: any one sensor's frame suffices). Sensors are counted by their slot in
        ``TrackTable.sensor_hit_t`` (the 16th and later share one).
    sees_both_s : float
        A sensor that detected both tracks this recently could have seen them apart.
    """

    def __init__(
        self,
        distance_m: float = 0.35,
        after_s: float = 0.5,
        max_speed_difference_mps: float = 0.6,
        distinct_s: float = 5.0,
        fresh_s: float = 0.3,
        reattach_speed_mps: float = 1.5,
        walking_m: float = 0.3,
        gate: float | None = None,
        noise_rate: float = 0.1,
        distinct_sensors: int = 1,
        sees_both_s: float = 1.0,
    ) -> None:
        self.distance_m = distance_m
        self.after_s = after_s
        self.max_speed_difference_mps = max_speed_difference_mps
        self.distinct_s = distinct_s
        self.fresh_s = fresh_s
        self.reattach_speed_mps = reattach_speed_mps
        self.walking_m = walking_m
        self.gate = gate
        self.noise_rate = noise_rate
        self.distinct_sensors = distinct_sensors
        self.sees_both_s = sees_both_s
        self._noise_var: dict[int, float] = {}
        self._close_since: dict[tuple[int, int], float] = {}
        self._last_close: dict[tuple[int, int], float] = {}
        # (lower id, higher id) -> when any sensor last saw them apart; and, only with
        # distinct_sensors > 1, -> {sensor slot: when it did} (the inner dicts are
        # replaced, never changed, so a snapshot may share them)
        self._distinct: dict[tuple[int, int], float] = {}
        self._apart_by: dict[tuple[int, int], dict[int, float]] = {}
        # only where ``observe`` is told which rows a frame proves apart: pairs any frame
        # detected together lately, kept a body's depth apart without proving two people
        self._together: dict[tuple[int, int], float] = {}

    def snapshot(self) -> tuple[dict[Any, Any], ...]:
        """Pair timers, the tracks' noise and who saw pairs apart (independent copies)."""
        return (
            dict(self._close_since),
            dict(self._last_close),
            dict(self._distinct),
            dict(self._noise_var),
            dict(self._apart_by),
            dict(self._together),
        )

    def restore(self, state: tuple[dict[Any, Any], ...]) -> None:
        """Return to a snapshot.

        One taken before the tracks' noise was kept has none; one taken before the
        sensors that saw a pair apart were kept has none either (each pair then counts
        as seen apart by one sensor); nor has one taken before the pairs merely detected
        together were kept.
        """
        dicts = [dict(d) for d in state] + [{} for _ in range(6 - len(state))]
        self._close_since, self._last_close, self._distinct, self._noise_var = dicts[:4]
        self._apart_by, self._together = dicts[4], dicts[5]
        if len(state) < 5:
            self._apart_by = {pair: {-1: s} for pair, s in self._distinct.items()}

    def observe(
        self,
        table: TrackTable,
        rows: np.ndarray,
        t: float,
        noise: np.ndarray | None = None,
        sensor: int = 0,
        apart: np.ndarray | None = None,
    ) -> None:
        """Tracks ``rows`` were detected in one frame of ``sensor``: it saw close pairs apart.

        ``sensor`` is the sensor's slot (:func:`~openptrack_py.tracking.state.sensor_slot`).

        ``noise`` ``(len(rows), 2, 2)`` is each row's detection's measurement covariance,
        averaged into the track's measurement variance. ``apart`` (a mask over ``rows``)
        keeps only the rows whose detections prove them apart from the others (all when
        ``None``): where gates overlap, a detection could have been another track's, and
        a person's second track that took a neighbour's or a stray detection beside the
        person's own would otherwise count as a second person and never be merged. With
        ``distinct_sensors`` 1 all the rows still count as detected together, which keeps
        two tracks a body's depth apart (:meth:`distinct_rows`) without proving them two
        people.
        """
        if self.after_s <= 0:
            return
        if noise is not None and self.gate is not None:
            var = 0.5 * (noise[:, 0, 0] + noise[:, 1, 1])
            for i, v in zip(table.ids[rows].tolist(), var.tolist(), strict=True):
                old = self._noise_var.get(i)
                self._noise_var[i] = v if old is None else old + self.noise_rate * (v - old)
        if apart is not None:
            if self.distinct_sensors == 1:  # with more, only proof keeps tracks apart
                for pair in self._close_ids(table, rows):
                    self._together[pair] = t
            rows = rows[apart]
        for pair in self._close_ids(table, rows):
            self._distinct[pair] = t
            if self.distinct_sensors > 1:
                self._apart_by[pair] = {**self._apart_by.get(pair, {}), sensor: t}

    def _close_ids(self, table: TrackTable, rows: np.ndarray) -> list[tuple[int, int]]:
        """Id pairs (lower first) of ``rows`` near enough to be confused."""
        if len(rows) < 2:
            return []
        ii, jj = close_pairs(
            table.x[rows, 0:2], 2.0 * self._reach(self._track_var(table.ids[rows]))
        )
        ids_i, ids_j = table.ids[rows[ii]].tolist(), table.ids[rows[jj]].tolist()
        return [(a, b) if a < b else (b, a) for a, b in zip(ids_i, ids_j, strict=True)]

    def distinct_rows(self, table: TrackTable, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Row pairs ``(a, b)`` of tracks to keep a body's depth apart at ``t``.

        Those known to be two people, and (where ``observe`` was told which rows a frame
        proves apart, and one sensor's frame is proof) those detected together lately.
        """
        row_of = {int(i): r for r, i in enumerate(table.ids.tolist())}
        pairs = [
            p
            for p, s in self._distinct.items()
            if t - s < self.distinct_s and p[0] in row_of and p[1] in row_of
        ]
        out = np.array([(row_of[a], row_of[b]) for a, b in pairs], dtype=np.intp).reshape(-1, 2)
        if self.distinct_sensors > 1:
            out = out[self._enough_sensors(table, t, pairs, out)]
        elif self._together:
            known = set(pairs)
            more = [
                (row_of[p[0]], row_of[p[1]])
                for p, s in self._together.items()
                if t - s < self.distinct_s and p not in known and p[0] in row_of and p[1] in row_of
            ]
            out = np.concatenate([out, np.array(more, dtype=np.intp).reshape(-1, 2)])
        return out[:, 0], out[:, 1]

    def _enough_sensors(
        self, table: TrackTable, t: float, pairs: list[tuple[int, int]], rows: np.ndarray
    ) -> np.ndarray:
        """Mask of ``pairs`` seen apart by enough of the sensors that detected both lately.

        ``pairs`` are ids (lower first), ``rows (n, 2)`` their rows.
        """
        if not len(pairs):
            return np.zeros(0, dtype=bool)
        apart = np.array(
            [
                sum(t - s < self.distinct_s for s in self._apart_by.get(p, {}).values())
                for p in pairs
            ],
            dtype=int,
        )
        hit = table.sensor_hit_t
        lately = t - self.sees_both_s
        seen = (hit[rows[:, 0]] > lately) & (hit[rows[:, 1]] > lately)
        return apart >= np.clip(seen.sum(axis=1), 1, self.distinct_sensors)

    def reattach(
        self, table: TrackTable, t: float, new: np.ndarray, lost_after_s: float
    ) -> list[tuple[int, int]]:
        """Pairs ``(lost_row, new_row)``: a just-confirmed track is a lost one seen again.

        Parameters
        ----------
        table : TrackTable
            The tracks.
        t : float
            Now.
        new : ndarray
            Rows confirmed in this step.
        lost_after_s : float
            A confirmed track unseen this long is lost.
        """
        lost = self._lost(table, t, lost_after_s)
        if self.reattach_speed_mps <= 0 or not len(new) or not len(lost):
            return []
        ok, gap = self._within_reach(table, new, lost)
        out: list[tuple[int, int]] = []
        used: set[int] = set()
        for i, j in sorted(zip(*np.nonzero(ok), strict=True), key=lambda ij: gap[ij]):
            a, b = int(lost[j]), int(new[i])
            if a in used or b in used:
                continue
            out.append((a, b))
            used.update((a, b))
        return out

    def continuations(self, table: TrackTable, t: float, lost_after_s: float) -> np.ndarray:
        """Mask of tentative tracks that may be a lost person who was walking, seen again.

        A person who walks behind a pillar reappears further along, within reach of
        where their track was lost: their new track need not prove again that it moves.
        Only a track that was walking when it was lost vouches (a track left on a static
        false positive was not), only for a new track started after it was lost, and
        only for one: the new track that started nearest to where it was last seen. A
        person reappears once; in a crowd, a split blob or a false positive that starts
        a track beside the person's new one is not vouched for too.
        """
        out = np.zeros(len(table), dtype=bool)
        if self.reattach_speed_mps <= 0:
            return out
        new = np.flatnonzero(~table.confirmed)
        lost = self._lost(table, t, lost_after_s)
        if not len(new) or not len(lost):
            return out
        lost = lost[self._walking(table, lost)]
        if len(lost):
            ok, gap = self._within_reach(table, new, lost)
            gap = np.where(ok, gap, np.inf)
            nearest = np.argmin(gap, axis=0)
            vouched = np.isfinite(gap[nearest, np.arange(len(lost))])
            out[new[nearest[vouched]]] = True
        return out

    @staticmethod
    def _lost(table: TrackTable, t: float, lost_after_s: float) -> np.ndarray:
        return np.flatnonzero(table.confirmed & (t - table.last_seen > lost_after_s))

    def _within_reach(
        self, table: TrackTable, new: np.ndarray, lost: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(len(new), len(lost))``: started after the loss, within walking reach; gaps."""
        gap = np.hypot(
            table.birth_xy[new, None, 0] - table.recent_xy[None, lost, 0],
            table.birth_xy[new, None, 1] - table.recent_xy[None, lost, 1],
        )
        elapsed = table.first_seen[new, None] - table.last_seen[None, lost]
        reach = self.distance_m + self.reattach_speed_mps * np.maximum(elapsed, 0.0)
        return (elapsed > 0) & (gap <= reach), gap

    def _walking(self, table: TrackTable, rows: np.ndarray) -> np.ndarray:
        """Whether each track's estimate moved ``walking_m`` in its last second seen."""
        ht, hxy = table.hist_t[rows], table.hist_xy[rows]
        recent = (ht >= table.last_seen[rows, None] - 1.0) & (ht <= table.last_seen[rows, None])
        first = np.argmin(np.where(recent, ht, np.inf), axis=1)
        last = np.argmax(np.where(recent, ht, -np.inf), axis=1)
        idx = np.arange(len(rows))
        moved = np.hypot(*(hxy[idx, last] - hxy[idx, first]).T)
        return recent.any(axis=1) & (moved >= self.walking_m)

    def merge(self, table: TrackTable, t: float) -> list[tuple[int, int]]:
        """Pairs ``(keep_row, drop_row)`` to merge now; each row in at most one pair."""
        if self.after_s <= 0:
            return []
        if len(self._noise_var) > 2 * len(table):  # forget the tracks that are gone
            live = set(table.ids.tolist())
            self._noise_var = {i: v for i, v in self._noise_var.items() if i in live}
        # detected by any sensor, whether or not that kept the track alive (every
        # detection that moves last_seen also stamps sensor_hit_t): two tracks sharing
        # one person's detections share their support too, and one of them often falls
        # below the keepalive level
        detected = table.sensor_hit_t.max(axis=1, initial=-np.inf)
        rows = np.flatnonzero(table.confirmed & (t - detected <= self.fresh_s))
        close = self._close_pairs(table, rows)
        for pair in close:
            self._last_close[pair] = t
        # a pair stays "close" through brief separations (noise), not through long ones
        apart = [p for p, s in self._last_close.items() if t - s > self.after_s]
        for pair in apart:
            self._last_close.pop(pair, None)
            self._close_since.pop(pair, None)
        self._distinct = {p: s for p, s in self._distinct.items() if t - s < self.distinct_s}
        self._together = {p: s for p, s in self._together.items() if t - s < self.distinct_s}
        self._apart_by = {p: s for p, s in self._apart_by.items() if p in self._distinct}
        if self.distinct_sensors > 1:
            rows = np.array([v[0:2] for v in close.values()], dtype=np.intp).reshape(-1, 2)
            enough = self._enough_sensors(table, t, list(close), rows).tolist()
            known = dict(zip(close, enough, strict=True))
        else:
            known = {p: p in self._distinct for p in close}
        out: list[tuple[int, int]] = []
        used: set[int] = set()
        for pair, (ra, rb, _gap) in sorted(close.items(), key=lambda kv: kv[1][2]):
            if known[pair]:
                self._close_since.pop(pair, None)
                continue
            since = self._close_since.setdefault(pair, t)
            if t - since < self.after_s or ra in used or rb in used:
                continue
            older_first = (table.first_seen[ra], table.ids[ra]) <= (
                table.first_seen[rb],
                table.ids[rb],
            )
            out.append((ra, rb) if older_first else (rb, ra))
            used.update((ra, rb))
            self._close_since.pop(pair, None)
        return out

    def _close_pairs(
        self, table: TrackTable, rows: np.ndarray
    ) -> dict[tuple[int, int], tuple[int, int, float]]:
        """Pairs of ``rows`` close in position and velocity, by (lower id, higher id)."""
        if len(rows) < 2:
            return {}
        x = table.x[rows]
        var = self._track_var(table.ids[rows])
        ii, jj = close_pairs(x[:, 0:2], self._reach(var))
        gap = np.hypot(x[ii, 0] - x[jj, 0], x[ii, 1] - x[jj, 1])
        dv = np.hypot(x[ii, 2] - x[jj, 2], x[ii, 3] - x[jj, 3])
        radius, speed = self._limits(table, rows, var, ii, jj)
        keep = (gap <= radius) & (dv <= speed)
        ii, jj, gap = ii[keep], jj[keep], gap[keep]
        out = {}
        for i, j, g in zip(ii.tolist(), jj.tolist(), gap.tolist(), strict=True):
            ra, rb = int(rows[i]), int(rows[j])
            a, b = int(table.ids[ra]), int(table.ids[rb])
            out[(a, b) if a < b else (b, a)] = (ra, rb, g)
        return out

    def _track_var(self, ids: np.ndarray) -> np.ndarray:
        """Each track's average measurement variance per axis (0 while unknown or unused)."""
        if self.gate is None:
            return np.zeros(len(ids))
        return np.array([self._noise_var.get(i, 0.0) for i in ids.tolist()])

    def _reach(self, var: np.ndarray) -> float:
        """The largest pair distance that may count as close among tracks of ``var``."""
        if self.gate is None or not len(var):
            return self.distance_m
        return max(self.distance_m, math.sqrt(self.gate * 2.0 * float(var.max())))

    def _limits(
        self, table: TrackTable, rows: np.ndarray, var: np.ndarray, ii: np.ndarray, jj: np.ndarray
    ) -> tuple[np.ndarray | float, np.ndarray | float]:
        """How far apart, and how differently moving, pairs ``(rows[ii], rows[jj])`` may be.

        ``var`` is the measurement variance of each of ``rows``.
        """
        if self.gate is None:
            return self.distance_m, self.max_speed_difference_mps
        radius = np.maximum(self.distance_m, np.sqrt(self.gate * (var[ii] + var[jj])))
        cov = table.cov[rows]
        w = 0.5 * (cov[:, 2, 2] + cov[:, 3, 3])
        speed = np.maximum(self.max_speed_difference_mps, np.sqrt(self.gate * (w[ii] + w[jj])))
        return radius, speed


class NoMerging:
    """Never merge tracks."""

    def observe(
        self,
        table: TrackTable,
        rows: np.ndarray,
        t: float,
        noise: np.ndarray | None = None,
        sensor: int = 0,
        apart: np.ndarray | None = None,
    ) -> None:
        """Nothing to remember."""

    def merge(self, table: TrackTable, t: float) -> list[tuple[int, int]]:
        """No pairs."""
        return []

    def distinct_rows(self, table: TrackTable, t: float) -> tuple[np.ndarray, np.ndarray]:
        """None known."""
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty

    def reattach(
        self, table: TrackTable, t: float, new: np.ndarray, lost_after_s: float
    ) -> list[tuple[int, int]]:
        """No pairs."""
        return []

    def continuations(self, table: TrackTable, t: float, lost_after_s: float) -> np.ndarray:
        """None."""
        return np.zeros(len(table), dtype=bool)
