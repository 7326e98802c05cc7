"""Re-identification: lost identities wait in a pool, young tracks take them back.

OpenPTrack v2 returns a lost face to a pool and matches it again; norfair keeps dead
tracks for re-identification. :class:`ReidPool` does both, with evidence that can be
weighed: a confirmed track that ends leaves its identity in the pool for ``pool_s``,
with its colours over the visit (a longer memory than association's); a young track
gathers evidence for each pooled identity it could be (one it could have walked to
since), and takes one back once it is confirmed (and observed for ``reid_min_s``) and
its mean log-likelihood ratio (colours and faces each averaged over the observations
that carry them, the two means added) passes ``reid_mean_llr``, has the posterior
``reid_min_posterior`` against the site's rate of returns (:mod:`.returns`), beats
every rival by ``reid_margin`` and beats everyone who was ever known to be someone
else, one-to-one (Hungarian). Evidence keeps coming in during the track's first
``reid_window_s``; a link it contradicts is undone and the identity goes back to the
pool. A person the pool missed once (back under a new identity) would leave two
identities in it, splitting every later return; the newer replaces the older when it
is pooled, unless those it looked like were there at the same time (two people).

The likelihoods themselves belong to the identity role that owns the pool
(:class:`LookJudge`, :class:`~.appearance.AppearanceIdentity`); the pool holds its
decisions and the evidence behind them.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Protocol

import numpy as np
from scipy.optimize import linear_sum_assignment

from openptrack_py.config.identity import IdentityConfig
from openptrack_py.tracking.identity.models import PooledIdentity, Side, TrackModels
from openptrack_py.tracking.identity.returns import ReturnRate, link_posterior
from openptrack_py.tracking.lookup import find_sorted
from openptrack_py.tracking.state import DetectionArrays, TrackTable

MIN_REID_OBSERVATIONS = 10
"""Observations of a young track against a pooled identity before their mean counts."""
Evidence = tuple[float, float, float, float]
"""A young track's evidence against a pooled identity: the sum and weight of its colour
log-likelihood ratios, then of its face ones."""
_NO_EVIDENCE: Evidence = (0.0, 0.0, 0.0, 0.0)


class LookJudge(Protocol):
    """What the pool asks of the identity role: its settings, models and likelihoods."""

    cfg: IdentityConfig
    models: TrackModels

    @property
    def uses_heights(self) -> bool:
        """Whether heights are a cue."""

    @property
    def faces_ready(self) -> bool:
        """Whether identity embeddings can be compared yet."""

    def pair_llr(self, a: Side, b: Side, rowwise: bool = False) -> np.ndarray:
        """Log-likelihood ratio of "same person" of every pair (or of ``a[k]``, ``b[k]``)."""

    def models_side(
        self, rows: np.ndarray, settled: np.ndarray | None = None, visit: bool = False
    ) -> Side:
        """Track models ``rows`` as one side of a comparison."""

    def height_worth(self) -> float:
        """What a height alone says of who someone is, against a clean colour (0-1)."""


class ReidPool:
    """The pool of lost identities and the links young tracks made to them.

    Parameters
    ----------
    judge : LookJudge
        The identity role whose settings (pool time, windows, evidence levels), models
        and likelihoods the pool uses.
    counters : dict
        Where ``reidentified`` and ``unlinked`` are counted.
    """

    def __init__(self, judge: LookJudge, counters: dict[str, int]) -> None:
        self.judge = judge
        self.counters = counters
        self.pool: tuple[PooledIdentity, ...] = ()
        self.links: dict[int, PooledIdentity] = {}
        # through the setter below, which also empties the means kept per track
        self.reid_ev: dict[int, dict[int, Evidence]] = {}
        self.resembled: dict[int, tuple[int, ...]] = {}
        self.since: dict[int, float] = {}  # linked tracks: when their identity began
        self.returns = ReturnRate()

    @property
    def reid_ev(self) -> dict[int, dict[int, Evidence]]:
        """Each young track's evidence for each pooled identity it could be."""
        return self._reid_ev

    @reid_ev.setter
    def reid_ev(self, evidence: dict[int, dict[int, Evidence]]) -> None:
        self._reid_ev = evidence
        # per track: the identities it has evidence for and its means, until it changes
        self._means_of: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def _pop_evidence(self, tid: int) -> dict[int, Evidence] | None:
        self._means_of.pop(tid, None)
        return self._reid_ev.pop(tid, None)

    @property
    def cfg(self) -> IdentityConfig:
        """The identity role's settings, as they are now."""
        return self.judge.cfg

    # ----------------------------------------------------------------- events

    def ended(
        self,
        table: TrackTable,
        rows: np.ndarray,
        mrows: np.ndarray,
        reason: str,
        lost_at: dict[int, float],
    ) -> None:
        """Tracks ``rows`` (model rows ``mrows``) end: a confirmed person's identity is pooled.

        ``reason`` as for :meth:`~.appearance.AppearanceIdentity.ended`; ``lost_at``: when
        the person of a track handed over was lost (taken out of it as used).
        """
        m = self.judge.models
        pooled = list(self.pool)
        ids = table.ids[rows]
        for row, tid, mr in zip(rows.tolist(), ids.tolist(), mrows.tolist(), strict=True):
            link = self.links.pop(tid, None)
            evidence = self._pop_evidence(tid)
            if evidence and link is None:  # lost before its window was over
                self._resemble(tid, evidence)
            resembled = self.resembled.pop(tid, ())
            began = self.since.pop(tid, None)
            if mr < 0:
                continue
            keep = reason in ("deleted", "handed over") and bool(table.confirmed[row])
            heights = m.hgt_n[mr] if self.judge.uses_heights else 0.0
            keep &= max(m.sig_n[mr], heights) >= self.cfg.min_observations or m.emb_w[mr] > 0
            if keep and self.cfg.pool_s > 0:
                born = float(m.born[mr]) if began is None else began
                pooled.append(
                    PooledIdentity(
                        stable=int(m.stable[mr]), sig=m.visit[mr].copy(), sig_n=float(m.sig_n[mr]),
                        emb=m.emb[mr].copy(), emb_w=float(m.emb_w[mr]),
                        xy=table.recent_xy[row].copy(),
                        lost_at=lost_at.pop(tid, float(table.last_seen[row])),
                        name_ev=m.name_ev[mr].copy(), **self._impostors(mr),
                        hgt=float(m.hgt[mr]), hgt_n=float(m.hgt_n[mr]), born_at=born,
                    )
                )  # fmt: skip
                # one person, one pooled identity: the newest (see _resemble)
                pooled = [e for e in pooled if e.stable not in resembled]
            elif link is not None:
                pooled.append(link)  # a duplicate's borrowed identity is free again
        self.pool = tuple(pooled)

    def exchange(self, a: int, b: int) -> None:
        """Tracks ``a`` and ``b`` exchanged identities: their evidence goes with them."""
        for table in (self.reid_ev, self._means_of, self.resembled, self.since):
            swap_entries(table, a, b)

    def follow_roster(self, mapping: np.ndarray) -> None:
        """Pooled evidence for names follows the roster (new name ``k`` was ``mapping[k]``)."""
        self.pool = tuple(replace(e, name_ev=remap(e.name_ev, mapping)) for e in self.pool)

    # --------------------------------------------------------------- evidence

    def gather(
        self, mrows: np.ndarray, cols: np.ndarray, dets: DetectionArrays, seen: Side, t: float
    ) -> None:
        """Young tracks' observations add to their evidence for the pooled identities.

        ``seen``: the observations (detections ``cols`` of model rows ``mrows``), their
        colours and heights marked where they describe their person alone, heights
        corrected for the sensor's error.
        """
        m, judge = self.judge.models, self.judge
        young = (t - m.born[mrows] <= self.cfg.reid_window_s) & (
            m.own[mrows] | np.isin(m.ids[mrows], list(self.links))
        )
        if not young.any():
            return
        mrows, cols, seen = mrows[young], cols[young], seen.take(np.flatnonzero(young))
        has_sig, has_hgt = seen.sig_ok, seen.hgt_ok
        entries = self.pool + tuple(
            self.links[int(m.ids[r])] for r in mrows if int(m.ids[r]) in self.links
        )
        if not entries:
            return
        pooled = self.side(entries)
        # colours (and heights) and faces are two cues, each averaged over the
        # observations that carry it, their means added (they are independent given who
        # it is): faces seen in a fifth of the frames count fully, not by a fifth
        llr = judge.pair_llr(replace(seen, emb_w=np.zeros_like(seen.emb_w)), pooled)
        faces = np.zeros_like(llr)
        face_w = np.zeros_like(llr)
        if judge.faces_ready and seen.emb_w.any():
            faces_only = Side(seen.sig, np.zeros_like(seen.sig_ok), seen.emb, seen.emb_w)
            faces = judge.pair_llr(faces_only, pooled)
            face_w = seen.emb_w[:, None] * pooled.emb_w[None, :]
        where = np.array([e.xy for e in entries])
        since = np.array([e.lost_at for e in entries])
        gap = np.linalg.norm(dets.xy[cols][:, None, :] - where[None, :, :], axis=2)
        # an observation counts in a mean as much as it can say: a clean colour fully, a
        # height alone as much as heights tell people apart against colours, a face by
        # its confidence where the pooled identity has one (none before faces compare)
        alone = np.where(has_hgt, judge.height_worth(), 0.0)
        weight = np.where(has_sig, 1.0, np.minimum(alone, 1.0)).tolist()
        reach = self.cfg.reid_max_speed_mps * np.maximum(t - since, 0.0) + self.cfg.reid_margin_m
        for k, r in enumerate(mrows.tolist()):
            ev = self.reid_ev.setdefault(int(m.ids[r]), {})
            self._means_of.pop(int(m.ids[r]), None)
            for e, value, face, fw, ok in zip(
                entries, llr[k].tolist(), faces[k].tolist(), face_w[k].tolist(),
                (gap[k] <= reach).tolist(), strict=True,
            ):  # fmt: skip
                if ok:
                    total, n, f_total, f_n = ev.get(e.stable, _NO_EVIDENCE)
                    ev[e.stable] = (total + value, n + weight[k], f_total + face, f_n + fw)

    def side(self, entries: tuple[PooledIdentity, ...]) -> Side:
        """Pooled identities as one side of a comparison."""
        enough = self.cfg.min_observations
        side = Side(
            np.array([e.sig for e in entries]),
            np.array([e.sig_n >= enough for e in entries]),
            np.array([e.emb for e in entries]),
            np.array([float(e.emb_w > 0) for e in entries]),
        )
        if not self.judge.uses_heights:
            return side
        return replace(
            side,
            hgt=np.array([e.hgt for e in entries]),
            hgt_ok=np.array([e.hgt_n >= enough for e in entries]),
        )

    # -------------------------------------------------------------- decisions

    def decide(self, table: TrackTable, t: float) -> None:
        """Expire the pool, revisit links, settle finished windows, link young tracks."""
        cfg, m = self.cfg, self.judge.models
        self.pool = tuple(e for e in self.pool if t - e.lost_at <= cfg.pool_s)
        linked = list(self.links)
        rows = m.rows(np.array(linked, dtype=np.int64)).tolist()
        for tid, row in zip(linked, rows, strict=True):
            if row < 0:
                continue
            entry = self.links[tid]
            if t - m.born[row] > cfg.reid_window_s:
                del self.links[tid]  # settled
                self._settle(tid, linked=True)
            elif mean_evidence(self.reid_ev.get(tid, {}).get(entry.stable)) <= cfg.unlink_evidence:
                del self.links[tid]
                m.stable[row], m.own[row] = tid, True
                self.since.pop(tid, None)
                self.pool += (entry,)
                self.counters["unlinked"] += 1
        unlinked = [k for k in self.reid_ev if k not in self.links]
        rows = m.rows(np.array(unlinked, dtype=np.int64)).tolist()
        for tid, row in zip(unlinked, rows, strict=True):
            if row < 0:
                self._pop_evidence(tid)
            elif t - m.born[row] > cfg.reid_window_s:
                self._settle(tid, linked=False)
        self._link(table, t)

    def _settle(self, tid: int, linked: bool) -> None:
        """Track ``tid``'s re-identification window is over: its evidence joins the prior."""
        evidence = self._pop_evidence(tid) or {}
        self.returns.add(np.array([mean_evidence(e) for e in evidence.values()]))
        if not linked:
            self._resemble(tid, evidence)

    def _resemble(self, tid: int, evidence: dict[int, Evidence]) -> None:
        """Which pooled identities track ``tid``, which took none, may be the person of.

        A track that looked like some (a mean of at least ``reid_mean_llr``, within
        ``reid_margin`` of its best) may be their person, back under a new identity: the
        earlier identities of one person who was not taken back before. Its pooled
        identity, when it is lost, replaces theirs: left side by side, the person's
        identities would split the posterior at every later return, and none would
        ever be taken back. Not when two of them were there at the same time: they are
        two people, and the track can be at most one of them.
        """
        means = {stable: mean_evidence(e) for stable, e in evidence.items()}
        best = max(means.values(), default=-np.inf)
        if best < self.cfg.reid_mean_llr:
            return
        floor = max(best - self.cfg.reid_margin, self.cfg.reid_mean_llr)
        alike = [e for e in self.pool if means.get(e.stable, -np.inf) >= floor]
        if not alike:
            return
        born, lost = np.array([(e.born_at, e.lost_at) for e in alike]).T
        together = (born[:, None] <= lost[None, :]) & (born[None, :] <= lost[:, None])
        if together.sum() == len(alike):  # each only with itself
            self.resembled[tid] = tuple(e.stable for e in alike)

    def _link(self, table: TrackTable, t: float) -> None:
        """Young confirmed tracks take back the pooled identities they clearly are.

        The test is on the *mean* log-likelihood ratio of a track's observations against
        each pooled identity (successive frames are far from independent: their sum
        would soon pass any threshold for a stranger who merely dresses alike), once
        the track has been observed for ``reid_min_s``.
        """
        cfg, m = self.cfg, self.judge.models
        if not self.pool or not self.reid_ev:
            return
        confirmed = set(table.ids[table.confirmed].tolist())
        rows = m.rows(np.array(list(self.reid_ev), dtype=np.int64))
        old_enough = {
            tid for tid, r in zip(self.reid_ev, rows.tolist(), strict=True)
            if r >= 0 and t - m.born[r] >= cfg.reid_min_s
        }  # fmt: skip
        cands = [
            tid for tid in self.reid_ev
            if tid not in self.links and tid in confirmed and tid in old_enough
        ]  # fmt: skip
        if not cands:
            return
        raw = self._means(cands)
        ev = np.maximum(raw, -1e3)
        # another young track for the same identity: two that look alike block each
        # other (better no link than a stranger's); rivals for the same track are in
        # the posterior's normalisation
        top_col = ev.max(axis=0, keepdims=True)
        second_col = np.full_like(top_col, -1e3)
        if ev.shape[0] > 1:
            second_col = np.sort(ev, axis=0)[-2:-1, :]
        rival_col = np.where(ev >= top_col, second_col, top_col)
        qualifies = (
            (ev >= cfg.reid_mean_llr)
            & (link_posterior(raw, self.returns.rate) >= cfg.reid_min_posterior)
            & (ev - rival_col >= cfg.reid_margin)
        )
        if qualifies.any():
            qualifies &= self._beats_impostors(cands)
        if not qualifies.any():
            return
        rows, cols = linear_sum_assignment(np.where(qualifies, -ev, 1e6))
        taken = set()
        for r, c in zip(rows.tolist(), cols.tolist(), strict=True):
            if not qualifies[r, c]:
                continue
            entry, tid = self.pool[c], cands[r]
            row = m.rows(np.array([tid]))[0]
            m.stable[row], m.own[row] = entry.stable, False
            m.name_ev[row] = np.maximum(m.name_ev[row], entry.name_ev)
            self.links[tid] = entry
            self.since[tid] = entry.born_at
            taken.add(c)
            self.counters["reidentified"] += 1
        self.pool = tuple(e for k, e in enumerate(self.pool) if k not in taken)

    def _means(self, cands: list[int]) -> np.ndarray:
        """``(C, P)``: each candidate's mean evidence for each pooled identity.

        As :func:`mean_evidence` of each pair (``-inf`` without evidence), computed per
        candidate over the identities it has evidence for.
        """
        stables, column = np.unique([e.stable for e in self.pool], return_inverse=True)
        out = np.full((len(cands), len(stables)), -np.inf)
        for k, tid in enumerate(cands):
            if tid not in self._means_of:
                evidence = self.reid_ev[tid]
                self._means_of[tid] = (
                    np.fromiter(evidence, dtype=np.int64, count=len(evidence)),
                    mean_evidences(np.array(list(evidence.values()), dtype=float).reshape(-1, 4)),
                )
            keys, means = self._means_of[tid]
            if not len(keys):
                continue
            at, pooled = find_sorted(stables, keys)
            out[k, at[pooled]] = means[pooled]
        return out[:, column.ravel()]

    def _beats_impostors(self, cands: list[int]) -> np.ndarray:
        """Whether each candidate looks more like each pooled identity than others did.

        ``(C, P)``: the candidate's model against the pooled one beats, by
        ``reid_margin``, the most alike anyone else known to be someone else ever looked
        (a candidate is not its own impostor).
        """
        judge = self.judge
        rows = judge.models.rows(np.array(cands, dtype=np.int64))
        everything = np.ones(len(rows), dtype=bool)  # a candidate's colours always count
        out = judge.pair_llr(judge.models_side(rows, everything, visit=True), self.side(self.pool))
        pool = self.pool
        itself = np.array(cands)[:, None] == np.array([e.impostor_id for e in pool])[None]
        impostor = np.where(
            itself,
            np.array([e.impostor_next for e in pool])[None],
            np.array([e.impostor for e in pool])[None],
        )
        return out >= impostor + self.cfg.reid_margin

    def _impostors(self, row: int) -> dict[str, float | int]:
        """How alike the people alive with track ``row`` look to it (see PooledIdentity).

        Score normalisation against an impostor cohort, as speaker and face verification
        do: a pooled identity is only taken by a look that beats every look known to be
        someone else's. The two most alike are kept: one of them may be the person's
        own new track, begun before this one was given up.
        """
        judge = self.judge
        m = judge.models
        others = np.setdiff1d(np.flatnonzero(m.sig_n >= self.cfg.min_observations), [row])
        if not len(others):
            return {}
        llr = judge.pair_llr(
            judge.models_side(np.array([row]), visit=True),
            judge.models_side(others, visit=True),
        )[0]
        order = np.argsort(llr)[::-1]
        return {
            "impostor": float(llr[order[0]]),
            "impostor_id": int(m.ids[others[order[0]]]),
            "impostor_next": float(llr[order[1]]) if len(order) > 1 else -np.inf,
        }


def mean_evidence(evidence: Evidence | None) -> float:
    """Mean log-likelihood ratio of ``(sum, observations, face sum, face observations)``.

    ``-inf`` without any evidence. Colours (with heights) and faces are each averaged
    over the observations that carry them, weighted by what they can say (see
    :meth:`ReidPool.gather`), and the means added; a cue with fewer than
    :data:`MIN_REID_OBSERVATIONS` says nothing yet.
    """
    if not evidence:
        return -np.inf
    total, n, f_total, f_n = evidence
    colours = total / n if n >= MIN_REID_OBSERVATIONS else 0.0
    return colours + (f_total / f_n if f_n >= MIN_REID_OBSERVATIONS else 0.0)


def mean_evidences(evidence: np.ndarray) -> np.ndarray:
    """:func:`mean_evidence` of each row of ``(n, 4)`` evidence."""
    total, n, f_total, f_n = evidence.T
    with np.errstate(divide="ignore", invalid="ignore"):
        colours = np.where(n >= MIN_REID_OBSERVATIONS, total / n, 0.0)
        faces = np.where(f_n >= MIN_REID_OBSERVATIONS, f_total / f_n, 0.0)
    return colours + faces


def swap_entries(table: dict, a: int, b: int) -> None:
    """The entries of keys ``a`` and ``b`` change places (a missing one stays missing)."""
    va, vb = table.pop(a, None), table.pop(b, None)
    if vb is not None:
        table[a] = vb
    if va is not None:
        table[b] = va


def remap(values: np.ndarray, mapping: np.ndarray) -> np.ndarray:
    """Per-name ``values`` moved to new places: new ``k`` takes old ``mapping[k]`` (-1: 0)."""
    out = np.zeros(len(mapping))
    old = mapping >= 0
    if old.any() and len(values):
        out[old] = values[mapping[old]]
    return out
