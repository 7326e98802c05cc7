"""The identity role: appearance in association, re-identification, registered names.

:class:`AppearanceIdentity` takes the best of the field's identity schemes:

* **Association** (DeepSORT's appearance term, the childcare tracking paper's weighted
  combination of motion, colour and face likelihoods, Eq. 4-9): each gated pair's cost
  gains ``-(w_c LLR_colour + w_f c LLR_embedding + w_h LLR_height)``, the
  log-likelihood ratios of "same person" learned online (:mod:`.likelihood`; heights
  corrected for each sensor's floor, :mod:`.heights`) and ``c`` the embedding's own
  confidence.
  It is added to admissible pairs only, so appearance re-ranks what the gate admitted
  and never admits anything.
* **Models** learn only from clean detections: confident, and not behind another
  detection in the image (a half-hidden person's colours are the neighbour's too).
* **Re-identification** (OpenPTrack v2's pool of lost faces, norfair's dead tracks kept
  for re-identification): a confirmed track that ends leaves its identity in a pool and
  a young track that clearly is one of them takes it back (:mod:`.reid`, which holds
  those decisions; this role gives it the models and likelihoods).
* **Exchanged identities** (identity management in multi-target tracking): two tracks
  that met and, once apart, each look like the other's identity from before they met,
  take their identities back (:mod:`.swaps`).
* **Names** (the paper's registered children, v2's named faces): evidence for each
  registered person accumulates the same way (bounded by shifting a track's evidence
  down as a whole, so its margins between names survive); a name needs ``link_margin``
  over the track's best other name (as v2 weighs a face against every registered face,
  not against a threshold alone: registered lookalikes leave a track unnamed, not named
  by a coin toss) and goes to tracks one-to-one by a Hungarian assignment over the
  evidence, with hysteresis, so no name is ever on two tracks at once.

All state is per track id, in arrays (:class:`~.models.TrackModels`), and is
snapshotted for the tracker's late-batch replay and its checkpoint.

This module is long because the role's uses of one evidence (association, exchanged
identities, names) share its models and likelihoods.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from scipy.optimize import linear_sum_assignment

from openptrack_py.config.identity import IdentityConfig
from openptrack_py.tracking.identity.handovers import GapWatch
from openptrack_py.tracking.identity.heights import HeightBias
from openptrack_py.tracking.identity.likelihood import (
    ISOLATION_M,
    PAIRWISE,
    DistanceLikelihood,
    distance_samples,
    rowwise_distance,
)
from openptrack_py.tracking.identity.models import PooledIdentity, Side, TrackLooks, TrackModels
from openptrack_py.tracking.identity.reid import (
    MIN_REID_OBSERVATIONS,
    Evidence,
    ReidPool,
    swap_entries,
)
from openptrack_py.tracking.identity.roster import Roster
from openptrack_py.tracking.identity.swaps import SwapWatch
from openptrack_py.tracking.neighbours import close_pairs, count_within
from openptrack_py.tracking.state import DetectionArrays, Looks, TrackTable

NAME_EVIDENCE_BOUND = 4.0
"""A track's evidence for a name stays within this many times ``link_evidence``."""
DISTINCT_OBSERVATIONS = 10
"""Clean signatures each of two tracks needs before they can be judged two people."""
BLOB_GAP_S = 1.0
"""Longest time a blob of two may go undetected and still be shared (seconds).

A blob of two people is detected as often as a person is: with a third to almost half
of a sensor's frames missed (OpenPTrack's paper: Kinect v2 misses 29.5 % in its crowd
test, 45 % in its occlusion test) and several sensors at 15-30 Hz, a second without any
detection is no blob at all. Two tracks that both went unseen for longer and then meet
on one detection are no evidence of two people (two tracks of people who walked out,
catching the next person in through the same door)."""


class AppearanceIdentity:
    """Identity from colour signatures and identity embeddings.

    Parameters
    ----------
    config : IdentityConfig
        Weights, windows and evidence levels.
    roster : Roster, optional
        Registered people.
    """

    needs_looks = True

    def __init__(self, config: IdentityConfig, roster: Roster | None = None) -> None:
        self.cfg = config
        self.colour = DistanceLikelihood(config.max_llr)
        self.face = DistanceLikelihood(config.max_llr)
        self.stature = DistanceLikelihood(config.max_llr)
        self.height_bias = HeightBias()
        self.models = TrackModels()
        self.named: dict[int, int] = {}
        self.apart: dict[tuple[int, int], float] = {}
        self.together: dict[tuple[int, int], float] = {}
        self.roster = Roster()
        self.swaps = SwapWatch(config.link_margin, config.reid_window_s, MIN_REID_OBSERVATIONS)
        self.gaps = GapWatch(config.link_margin, config.reid_window_s, MIN_REID_OBSERVATIONS)
        self.split: dict[int, float] = {}  # tracks to split now: when their person was lost
        self.counters = {"reidentified": 0, "unlinked": 0, "swapped_back": 0, "handed_over": 0}
        self.reid = ReidPool(self, self.counters)
        self.told: list[tuple[int, str]] = []  # name_track's calls, in order
        self.set_roster(roster or Roster())

    # ------------------------------------------------------- re-identification

    @property
    def pool(self) -> tuple[PooledIdentity, ...]:
        """Identities of lost people waiting to be recognised (:class:`.reid.ReidPool`)."""
        return self.reid.pool

    @pool.setter
    def pool(self, entries: tuple[PooledIdentity, ...]) -> None:
        self.reid.pool = entries

    @property
    def reid_ev(self) -> dict[int, dict[int, Evidence]]:
        """Young tracks' evidence for each pooled identity, by track id and identity."""
        return self.reid.reid_ev

    # ------------------------------------------------------------------ roster

    def set_roster(self, roster: Roster) -> None:
        """Use ``roster`` from now on (evidence for names kept by name)."""
        before, self.roster = self.roster.names, roster
        self._follow_roster(before)

    def _follow_roster(self, before: Sequence[str]) -> None:
        """Move name evidence kept for the names ``before`` to the roster's names."""
        old = {name: k for k, name in enumerate(before)}
        mapping = np.array([old.get(name, -1) for name in self.roster.names], dtype=np.int64)
        self.models.resize_names(mapping)
        self.reid.follow_roster(mapping)
        self.named = {
            tid: int(np.flatnonzero(mapping == k)[0])
            for tid, k in self.named.items()
            if (mapping == k).any()
        }

    @property
    def _name_bound(self) -> float:
        """The most evidence a track can hold for a name (and the least, negated)."""
        return NAME_EVIDENCE_BOUND * self.cfg.link_evidence

    def name_track(self, track_id: int, name: str) -> None:
        """Someone says the live track ``track_id`` is the registered ``name``.

        The track carries the name at once, with the most evidence a name can hold, and
        keeps it until its looks come to favour another registered person; any other
        track loses the name. A lookalike registered from their own track thus keeps
        their name by continuity, where looks alone would leave both unnamed. A
        late-batch replay from before this moment says it again.
        """
        self.told.append((int(track_id), name))
        self._pin(int(track_id), name)

    def _pin(self, track_id: int, name: str) -> None:
        row = self.models.rows(np.array([track_id]))[0]
        if row < 0 or name not in self.roster.names:
            return
        k = self.roster.names.index(name)
        ev = self.models.name_ev
        ev[:, k] = np.minimum(ev[:, k], 0.0)
        ev[row, k] = self._name_bound
        self.named = {tid: j for tid, j in self.named.items() if j != k}
        self.named[track_id] = k

    def looks_of(self, track_id: int) -> TrackLooks | None:
        """A live track's models (``None``: no such track)."""
        row = self.models.rows(np.array([track_id]))[0]
        if row < 0:
            return None
        m = self.models
        return TrackLooks(
            m.sig[row].copy(), float(m.sig_n[row]), m.emb[row].copy(),
            float(m.hgt[row]), float(m.hgt_n[row]),
        )  # fmt: skip

    # ------------------------------------------------------------ association

    def cost(
        self, table: TrackTable, dets: DetectionArrays, t: float, allowed: np.ndarray
    ) -> np.ndarray | None:
        """``-(w_c LLR_colour + w_f c LLR_embedding + w_h LLR_height)`` of the pairs ``allowed``.

        0 for the others (they cannot be assigned); ``None``: no opinion.
        """
        looks = dets.looks
        if looks is None or not len(table) or not len(dets):
            return None
        self.models.fit_dims(looks.signature.shape[1], looks.embedding.shape[1])
        rows = self.models.rows(table.ids)
        out = np.zeros((len(table), len(dets)))
        ti, dj = np.nonzero(allowed & (rows >= 0)[:, None])
        if len(ti):
            heights = None
            if self.uses_heights:
                heights = self.height_bias.correct(dets.sensor_id, dets.xy, dets.height)[dj]
            seen = _looks_side(looks, dj, heights=heights)
            out[ti, dj] = -self.pair_llr(self.models_side(rows[ti]), seen, rowwise=True)
        return out if out.any() else None

    # ----------------------------------------------------------------- events

    def started(
        self, table: TrackTable, rows: np.ndarray, dets: DetectionArrays, t: float
    ) -> None:
        """New tracks: each its own identity."""
        self.models.add(table.ids[rows], t)

    def observe(
        self,
        table: TrackTable,
        rows: np.ndarray,
        cols: np.ndarray,
        dets: DetectionArrays,
        t: float,
        certain: np.ndarray | None = None,
    ) -> None:
        """Learn from the step's updates, gather evidence, take decisions."""
        looks = dets.looks
        if looks is None or not len(rows):
            return
        m = self.models
        mrows = m.rows(table.ids[rows])
        ok = mrows >= 0
        if certain is None:
            certain = np.zeros(len(rows), dtype=bool)
        rows, cols, mrows, certain = rows[ok], cols[ok], mrows[ok], certain[ok]
        known = table.confirmed[rows] & (
            (m.sig_n[mrows] >= self.cfg.min_observations) | (m.emb_w[mrows] > 0)
        )
        self.gaps.seen(table.ids[rows], known, t, lambda ids: self.models_side(m.rows(ids)))
        # two people, not one person and a spurious second blob beside them (weaker,
        # and overlapping them in the image)
        sure = looks.clean[cols] & (dets.confidence[cols] >= self.cfg.clean_min_confidence)
        self._seen_apart(table, rows[sure], t)
        fit_c, fit_e = m.fit_dims(looks.signature.shape[1], looks.embedding.shape[1])
        where = (dets.xy[cols], table.x[:, 0:2])
        alone = count_within(where[0], where[1], self.cfg.share_distance_m) <= 1
        # a detection with another person within a body width may be both of them in
        # one blob: its colours are theirs mixed
        clean = looks.clean[cols] & alone
        clean &= dets.confidence[cols] >= self.cfg.clean_min_confidence
        confirmed = table.confirmed[rows]
        others = m.rows(table.ids)
        if fit_c:
            use = clean & looks.has_signature[cols]
            ready = m.sig_n >= self.cfg.min_observations
            self.colour.learn(
                *distance_samples(
                    m.sig, ready, mrows, looks.signature[cols], use & confirmed & certain,
                    use & confirmed, where, others, table.confirmed, "hellinger",
                )
            )  # fmt: skip
            m.learn_colour(
                mrows[use], looks.signature[cols[use]], self.cfg.model_rate, self.cfg.visit_rate
            )
        if fit_e:
            use = looks.embedding_weight[cols] > 0
            ready = m.emb_w > 0
            self.face.learn(
                *distance_samples(
                    m.emb, ready, mrows, looks.embedding[cols], use & confirmed & certain,
                    use & confirmed, where, others, table.confirmed, "cosine",
                )
            )  # fmt: skip
            m.learn_embedding(
                mrows[use], looks.embedding[cols[use]], looks.embedding_weight[cols[use]],
                self.cfg.model_rate,
            )  # fmt: skip
        heights = dets.height[cols]
        if self.uses_heights:
            learnable = (confirmed, certain, where, others)
            heights = self._learn_heights(table, mrows, cols, dets, clean, learnable, t)
        # what each detection says of who it is: colours and heights of clean ones,
        # identity embeddings of any
        has_sig = clean & looks.has_signature[cols]
        has_hgt = clean & (self.uses_heights and self.stature.ready)
        useful = has_sig | has_hgt | (looks.embedding_weight[cols] > 0)
        mrows, cols = mrows[useful], cols[useful]
        seen = _looks_side(looks, cols, has_sig[useful], heights[useful], has_hgt[useful])
        self._watch_swaps(table, m.ids[mrows], seen, t)
        self.gaps.observe(m.ids[mrows], seen, lambda a, b: self.pair_llr(a, b, rowwise=True))
        self.split.update(self.gaps.decide(t, table.ids))
        if len(mrows):
            self._gather_evidence(mrows, cols, dets, seen, t)
        self._decide(table, t)

    def _watch_swaps(self, table: TrackTable, ids: np.ndarray, seen: Side, t: float) -> None:
        """Pairs of settled tracks that meet are watched; exchanged identities swap back.

        ``seen``: this step's observations of tracks ``ids``.
        """
        m = self.models
        rows = np.flatnonzero(table.confirmed)
        mr = m.rows(table.ids[rows])
        has = mr >= 0
        rows, mr = rows[has], mr[has]
        rows = rows[(m.sig_n[mr] >= DISTINCT_OBSERVATIONS) | (m.emb_w[mr] > 0)]
        ii, jj = close_pairs(table.x[rows, 0:2], self.cfg.share_distance_m)
        if len(ii):
            pairs = _pairs(table.ids[rows[ii]], table.ids[rows[jj]])
            self.swaps.meet(pairs, t, lambda ids: self.models_side(m.rows(ids)))
        self.swaps.observe(ids, seen, t, lambda a, b: self.pair_llr(a, b, rowwise=True))
        for (a, b), before in self.swaps.decide(t, table.ids):
            self._exchange(a, b, before)

    def _exchange(self, a: int, b: int, before: Side) -> None:
        """Tracks ``a`` and ``b`` exchange identities (models, links, names, evidence).

        Each takes the other's looks from ``before`` they met (colours, embedding,
        height): since then each model has been learning the other person. Not while
        either holds a re-identification that may still be undone (undoing it gives
        the track back its own id, which after an exchange the other track holds).
        """
        if a in self.reid.links or b in self.reid.links:
            return
        m = self.models
        ra, rb = m.rows(np.array([a, b]))
        if ra < 0 or rb < 0:
            return
        m.exchange(int(ra), int(rb))
        rows, other = np.array([ra, rb]), np.array([1, 0])
        m.sig[rows] = before.sig[other]
        had = before.emb_w[other] > 0
        m.emb[rows[had]] = before.emb[other[had]]
        if before.hgt is not None and before.hgt_ok is not None:
            had = before.hgt_ok[other]
            m.hgt[rows[had]] = before.hgt[other[had]]
        swap_entries(self.named, a, b)
        self.reid.exchange(a, b)
        self.counters["swapped_back"] += 1

    @property
    def faces_ready(self) -> bool:
        """Whether identity embeddings can be compared yet (their likelihood learned)."""
        return self.face.ready

    @property
    def uses_heights(self) -> bool:
        """Whether heights are a cue (``height_weight`` > 0); if not, none is learned."""
        return self.cfg.height_weight > 0

    def _learn_heights(
        self,
        table: TrackTable,
        mrows: np.ndarray,
        cols: np.ndarray,
        dets: DetectionArrays,
        clean: np.ndarray,
        learnable: tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray], np.ndarray],
        t: float,
    ) -> np.ndarray:
        """Learn heights from one step's updates at ``t``; return them corrected.

        Each sensor's height error, the height likelihood and the tracks' height models.

        ``learnable``: per update, its track confirmed and motion alone certain, and the
        detections' and the tracks' positions and every table track's model row (as for
        colours).
        """
        m, enough = self.models, self.cfg.min_observations
        confirmed, certain, where, others = learnable
        raw = dets.height[cols]
        heights = self.height_bias.correct(dets.sensor_id, dets.xy[cols], raw)
        known = clean & confirmed
        self.height_bias.learn(
            dets.sensor_id, m.ids[mrows[known]], dets.xy[cols][known], raw[known], t
        )
        self.stature.learn(
            *distance_samples(
                m.hgt[:, None], m.hgt_n >= enough, mrows, heights[:, None],
                clean & confirmed & certain, clean & confirmed, where, others, table.confirmed,
                "height",
            )
        )  # fmt: skip
        m.learn_height(mrows[clean], heights[clean], self.cfg.visit_rate)
        return heights

    def handed_over(self, table: TrackTable) -> np.ndarray:
        """Rows of the tracks that follow someone else since a gap (:mod:`.handovers`)."""
        if not self.split:
            return np.zeros(0, dtype=np.int64)
        rows = np.flatnonzero(np.isin(table.ids, list(self.split)))
        alive = set(table.ids[rows].tolist())
        self.split = {i: s for i, s in self.split.items() if i in alive}
        self.counters["handed_over"] += len(rows)
        return rows

    def ended(
        self, table: TrackTable, rows: np.ndarray, t: float, reason: str = "deleted"
    ) -> None:
        """Tracks ``rows`` end: a confirmed person's identity waits in the pool.

        ``reason``: ``"deleted"`` (lost), ``"merged"`` (a duplicate folded into another
        track), ``"reattached"`` (its track id continues under an older one) or
        ``"handed over"`` (its track goes on with someone else, under a new id).
        """
        m = self.models
        ids = table.ids[rows]
        mrows = m.rows(ids)
        for tid in ids.tolist():
            self.named.pop(tid, None)
        self.reid.ended(table, rows, mrows, reason, self.split)
        m.drop(mrows[mrows >= 0])
        gone = set(ids.tolist())
        self.apart = {p: s for p, s in self.apart.items() if p[0] not in gone and p[1] not in gone}
        self.together = {p: s for p, s in self.together.items() if p in self.apart}

    def _seen_apart(self, table: TrackTable, rows: np.ndarray, t: float) -> None:
        """Tracks ``rows`` were detected in one sensor frame at ``t``: near pairs are two."""
        if len(rows) < 2:
            return
        ii, jj = close_pairs(table.x[rows, 0:2], ISOLATION_M)
        ids = table.ids[rows]
        for pair in _pairs(ids[ii], ids[jj]):
            self.apart[pair] = self.together[pair] = t

    def distinct(self, table: TrackTable, rows_a: np.ndarray, rows_b: np.ndarray) -> np.ndarray:
        """Pairs known to be two people: seen apart, and their looks say two people.

        The pair must have been detected as two people in one sensor frame while both
        tracks lived (two tracks of one person at a camera boundary never are), and its
        looks must disagree (log-likelihood ratio below ``-link_margin``, both models
        settled: ``DISTINCT_OBSERVATIONS`` clean signatures, or an embedding each).
        Where everyone dresses alike nobody is distinct.
        """
        m = self.models
        a, b = m.rows(table.ids[rows_a]), m.rows(table.ids[rows_b])
        pairs = _pairs(table.ids[rows_a], table.ids[rows_b])
        seen = np.array([p in self.apart for p in pairs], dtype=bool)
        ok = (a >= 0) & (b >= 0) & seen
        llr = np.zeros(len(a))
        known = np.zeros(len(a), dtype=bool)
        if self.colour.ready and m.sig.shape[1]:
            both = (
                ok & (m.sig_n[a] >= DISTINCT_OBSERVATIONS) & (m.sig_n[b] >= DISTINCT_OBSERVATIONS)
            )
            d = rowwise_distance("hellinger", m.sig[a[both]], m.sig[b[both]])
            llr[both] += self.cfg.appearance_weight * self.colour.llr(d)
            known |= both
        if self.face.ready and m.emb.shape[1]:
            both = ok & (m.emb_w[a] > 0) & (m.emb_w[b] > 0)
            d = rowwise_distance("cosine", m.emb[a[both]], m.emb[b[both]])
            llr[both] += self.cfg.embedding_weight * self.face.llr(d)
            known |= both
        return known & (llr <= -self.cfg.link_margin)

    def shares(
        self,
        table: TrackTable,
        lonely: np.ndarray,
        partner: np.ndarray,
        dets: DetectionArrays,
        cols: np.ndarray,
        t: float,
    ) -> np.ndarray:
        """Which ``lonely`` tracks may follow their ``partner``'s detection ``cols``.

        Known two people side by side: the pair last detected as two within
        ``share_max_s`` (two tracks that take one detection turn about, each seeing it
        as its own now and then, are no evidence of two people), explained by one
        detection without a gap of more than :data:`BLOB_GAP_S` since, and the
        detection looking at least as much like the two of them together (the mean of
        their colour models: a blob mixes their looks) as like the partner alone (the
        lonely one has left, and following the partner would make a ghost).
        """
        m = self.models
        pairs = _pairs(table.ids[lonely], table.ids[partner])
        since = np.array([self.apart.get(p, -np.inf) for p in pairs])
        shared = np.array([self.together.get(p, -np.inf) for p in pairs])
        ok = (t - since <= self.cfg.share_max_s) & (t - shared <= BLOB_GAP_S)
        gap = np.linalg.norm(table.x[lonely, 0:2] - table.x[partner, 0:2], axis=1)
        ok &= gap <= self.cfg.share_distance_m
        ok &= self.distinct(table, lonely, partner)
        if ok.any() and dets.looks is not None:
            who = m.rows(table.ids[np.concatenate([lonely, partner])])
            looks = dets.looks
            seen = _looks_side(looks, cols)
            lone, part = who[: len(lonely)], who[len(lonely) :]
            partner_side = self.models_side(part, settled=m.sig_n[part] >= 1)
            alone = self.pair_llr(seen, partner_side, rowwise=True)
            both = Side(
                0.5 * (m.sig[lone] + m.sig[part]), np.ones(len(lone), dtype=bool),
                m.emb[part], np.zeros(len(part)),
            )  # fmt: skip
            ok &= self.pair_llr(seen, both, rowwise=True) >= alone
        for k in np.flatnonzero(ok).tolist():
            self.together[pairs[k]] = t
        return ok

    def labels(self, ids: np.ndarray) -> tuple[list[int | None], list[str | None]]:
        """Per track of ``ids``: its ``stable_id`` and, when named, its name."""
        rows = self.models.rows(ids)
        stable = ids.copy()
        stable[rows >= 0] = self.models.stable[rows[rows >= 0]]
        names = self.roster.names
        named = (self.named.get(i) for i in ids.tolist())
        return stable.tolist(), [
            names[k] if k is not None and k < len(names) else None for k in named
        ]

    # --------------------------------------------------------------- learning

    def pair_llr(self, a: Side, b: Side, rowwise: bool = False) -> np.ndarray:
        """Log-likelihood ratio of "same person" (all three cues).

        ``(len(a), len(b))`` for every pair, or ``(len(a),)`` for the pairs ``a[k]``,
        ``b[k]`` when ``rowwise``.
        """

        def dist(kind: str, x: np.ndarray, y: np.ndarray) -> np.ndarray:
            return rowwise_distance(kind, x, y) if rowwise else PAIRWISE[kind](x, y)

        def outer(x: np.ndarray, y: np.ndarray) -> np.ndarray:
            return x * y if rowwise else x[:, None] * y[None, :]

        out = np.zeros(len(a.sig) if rowwise else (len(a.sig), len(b.sig)))
        cfg = self.cfg
        dim = a.sig.shape[1]
        if (
            self.colour.ready
            and dim
            and dim == b.sig.shape[1]
            and a.sig_ok.any()
            and b.sig_ok.any()
        ):
            llr = self.colour.llr(dist("hellinger", a.sig, b.sig))
            out += cfg.appearance_weight * llr * outer(a.sig_ok, b.sig_ok)
        dim = a.emb.shape[1]
        if self.face.ready and dim and dim == b.emb.shape[1] and a.emb_w.any() and b.emb_w.any():
            llr = self.face.llr(dist("cosine", a.emb, b.emb))
            out += cfg.embedding_weight * llr * outer(a.emb_w, b.emb_w)
        if (
            self.uses_heights
            and self.stature.ready
            and a.hgt_ok is not None
            and b.hgt_ok is not None
            and a.hgt_ok.any()
            and b.hgt_ok.any()
        ):
            llr = self.stature.llr(dist("height", a.hgt[:, None], b.hgt[:, None]))
            out += cfg.height_weight * llr * outer(a.hgt_ok, b.hgt_ok)
        return out

    def models_side(
        self, rows: np.ndarray, settled: np.ndarray | None = None, visit: bool = False
    ) -> Side:
        """Track models ``rows``; colours count where ``settled`` (default: enough seen).

        ``visit``: their colours over the visit (as pooled), not as they look now.
        """
        m = self.models
        if settled is None:
            settled = m.sig_n[rows] >= self.cfg.min_observations
        sig = (m.visit if visit else m.sig)[rows]
        side = Side(sig, settled, m.emb[rows], (m.emb_w[rows] > 0).astype(float))
        if not self.uses_heights:
            return side
        return replace(side, hgt=m.hgt[rows], hgt_ok=m.hgt_n[rows] >= self.cfg.min_observations)

    def _gather_evidence(
        self, mrows: np.ndarray, cols: np.ndarray, dets: DetectionArrays, seen: Side, t: float
    ) -> None:
        """Each observation adds to the evidence for names and pooled identities.

        ``seen`` as for :meth:`.reid.ReidPool.gather`.
        """
        m = self.models
        rho = self.cfg.evidence_per_observation
        if len(self.roster):
            sig, sig_ok = self.roster.references("signature", m.sig.shape[1])
            emb, emb_ok = self.roster.references("embedding", m.emb.shape[1])
            llr = self.pair_llr(
                seen, Side(sig, sig_ok, emb, emb_ok.astype(float), *self.roster.heights())
            )
            np.add.at(m.name_ev, mrows, rho * llr)
            # bounded, so a track that changed person can be renamed; a row is shifted
            # down as a whole (not clipped) so its margins between names survive (only
            # the rows just updated can have left the bounds)
            cap, touched = self._name_bound, np.unique(mrows)
            ev = m.name_ev[touched]
            ev -= np.maximum(ev.max(axis=1, initial=0.0) - cap, 0.0)[:, None]
            m.name_ev[touched] = np.maximum(ev, -cap)
        self.reid.gather(mrows, cols, dets, seen, t)

    def height_worth(self) -> float:
        """What a height alone says of who someone is, against a clean colour (0-1).

        The ratio of the two cues' separations (the mean log-likelihood ratio over same
        pairs): 0 where everyone is about as tall, 1 where heights tell people apart at
        least as well as colours, or when colours tell nothing.
        """
        height = self.cfg.height_weight * self.stature.separation()
        colour = self.cfg.appearance_weight * self.colour.separation()
        if height <= 0:
            return 0.0
        return 1.0 if colour <= 0 else min(height / colour, 1.0)

    # -------------------------------------------------------------- decisions

    def _decide(self, table: TrackTable, t: float) -> None:
        """Re-identification's decisions (:mod:`.reid`), then names."""
        self.reid.decide(table, t)
        self._name(table)

    def _name(self, table: TrackTable) -> None:
        """Names to confirmed tracks one-to-one, by evidence, with hysteresis."""
        m = self.models
        if not len(self.roster) or not len(m):
            self.named = {}
            return
        rows = m.rows(table.ids[table.confirmed])
        rows = rows[rows >= 0]
        if not len(rows):
            self.named = {}
            return
        raw = m.name_ev[rows]
        ev = raw.copy()
        ids = m.ids[rows]
        # a name needs ``link_margin`` over the track's best other name (lookalikes in
        # the roster leave the track unnamed rather than named by a coin toss); a held
        # name is kept until another overtakes it
        need = np.full(ev.shape, self.cfg.link_margin)
        for k, tid in enumerate(ids.tolist()):
            held = self.named.get(tid)
            if held is not None and held < ev.shape[1]:
                ev[k, held] += self.cfg.link_margin
                need[k, held] = 0.0
        eligible = (ev >= self.cfg.link_evidence) & (raw - _rival(raw) >= need)
        named: dict[int, int] = {}
        if eligible.any():
            r, c = linear_sum_assignment(np.where(eligible, -ev, 1e6))
            named = {int(ids[i]): int(j) for i, j in zip(r, c, strict=True) if eligible[i, j]}
        self.named = named

    # ------------------------------------------------------------------ state

    def snapshot(self) -> tuple:
        """Everything the late-batch replay and the checkpoint must restore."""
        reid = self.reid
        return (
            self.models.copy(), reid.pool, dict(reid.links),
            {k: dict(v) for k, v in reid.reid_ev.items()}, dict(self.named),
            self.colour.state(), self.face.state(), dict(self.apart), reid.returns.state(),
            dict(self.together), tuple(self.roster.names), len(self.told),
            self.stature.state(), self.height_bias.state(), dict(reid.resembled), dict(reid.since),
            self.swaps.state(), self.gaps.state(),
        )  # fmt: skip

    def restore(self, state: tuple) -> None:
        """Return to a :meth:`snapshot`."""
        models, pool, links, reid_ev, named, colour, face, apart, *rest = state
        reid = self.reid
        # checkpoints written before the time was kept hold a set: seen apart long ago
        self.apart = dict(apart) if isinstance(apart, dict) else dict.fromkeys(apart, -np.inf)
        if rest:  # checkpoints written before the return rate was kept lack it
            reid.returns.restore(rest[0])
        self.together = dict(rest[1]) if len(rest) > 1 else dict(self.apart)
        self.models = models.copy()
        reid.pool, reid.links, self.named = pool, dict(links), dict(named)
        # checkpoints written before faces were averaged apart hold (sum, observations)
        reid.reid_ev = {
            k: {s: (*e, 0.0, 0.0)[:4] for s, e in v.items()} for k, v in reid_ev.items()
        }
        self.colour.restore(colour)
        self.face.restore(face)
        if len(rest) > 5:  # checkpoints written before heights were modelled lack them
            self.stature.restore(rest[4])
            self.height_bias.restore(rest[5])
        else:
            self.stature, self.height_bias = DistanceLikelihood(self.cfg.max_llr), HeightBias()
        reid.resembled = dict(rest[6]) if len(rest) > 6 else {}
        reid.since = dict(rest[7]) if len(rest) > 7 else {}
        self.swaps.restore(rest[8] if len(rest) > 8 else ({}, -np.inf))
        self.gaps.restore(rest[9] if len(rest) > 9 else ({}, {}))
        self.split = {}
        if len(rest) > 2:  # the roster may have changed since: names follow by name
            self._follow_roster(rest[2])
            for track_id, name in self.told[rest[3] :]:  # said since: said again
                self._pin(track_id, name)
        elif self.models.name_ev.shape[1] != len(self.roster):
            self.models.name_ev = np.zeros((len(self.models), len(self.roster)))
            self.named = {}


def _pairs(ids_a: np.ndarray, ids_b: np.ndarray) -> list[tuple[int, int]]:
    """Each pair of track ids as a key, the smaller id first."""
    return [
        (a, b) if a < b else (b, a) for a, b in zip(ids_a.tolist(), ids_b.tolist(), strict=True)
    ]


def _looks_side(
    looks: Looks,
    cols: np.ndarray,
    has_sig: np.ndarray | None = None,
    heights: np.ndarray | None = None,
    has_hgt: np.ndarray | None = None,
) -> Side:
    """Detections ``cols`` of a batch; colours count where ``has_sig`` (default: any).

    ``heights`` (of the detections ``cols``) count where ``has_hgt`` (default: all); no
    height counts without them.
    """
    if heights is not None and has_hgt is None:
        has_hgt = np.ones(len(heights), dtype=bool)
    return Side(
        looks.signature[cols],
        looks.has_signature[cols] if has_sig is None else has_sig,
        looks.embedding[cols],
        looks.embedding_weight[cols],
        heights,
        has_hgt,
    )


def _rival(ev: np.ndarray) -> np.ndarray:
    """Per entry of ``ev (tracks, names)``: the row's best evidence for another name (>= 0).

    0 stands for a person who is not registered at all.
    """
    if ev.shape[1] < 2:
        return np.zeros_like(ev)
    order = np.argsort(ev, axis=1)
    first = np.take_along_axis(ev, order[:, -1:], axis=1)
    second = np.take_along_axis(ev, order[:, -2:-1], axis=1)
    best_other = np.where(np.arange(ev.shape[1])[None, :] == order[:, -1:], second, first)
    return np.maximum(best_other, 0.0)
