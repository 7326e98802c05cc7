"""Per-track appearance models, as arrays keyed by track id.

Each track has a colour model (the average of its clean signatures, an exponential
average once it has seen ``1 / rate`` of them: a DeepSORT-style gallery reduced to its
mean, which is what a hue histogram's comparison needs) and an embedding model (the
confidence-weighted mean direction of its identity embeddings), its stable identity, and
its evidence for each registered name.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from openptrack_py.tracking.lookup import find_sorted

_INT = np.int64


@dataclass
class TrackModels:
    """Every track's look and identity (one row per track, in no particular order).

    Parameters
    ----------
    ids : ndarray of int
        Track id of each row.
    sig, sig_n : ndarray
        Colour model ``(n, B)`` (summing to 1) and the clean signatures it averages.
    visit : ndarray
        ``(n, B)`` the same signatures averaged with a longer memory: the look a lost
        track leaves in the pool.
    emb, emb_w : ndarray
        Embedding model ``(n, D)`` (unit rows once any was seen) and its weight.
    hgt, hgt_n : ndarray
        Height model (the average of the clean detections' heights, metres, with the
        visit's memory) and the heights it averages.
    stable : ndarray of int
        The identity published as ``stable_id``.
    own : ndarray of bool
        Whether ``stable`` is the track's own (not taken from a pooled identity).
    born : ndarray
        Time of the first detection of the identity's track (it goes with the identity
        when two tracks exchange identities).
    name_ev : ndarray
        ``(n, R)`` evidence (log-likelihood ratio) for each registered name.
    """

    ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=_INT))
    sig: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    sig_n: np.ndarray = field(default_factory=lambda: np.zeros(0))
    visit: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    emb: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    emb_w: np.ndarray = field(default_factory=lambda: np.zeros(0))
    hgt: np.ndarray = field(default_factory=lambda: np.zeros(0))
    hgt_n: np.ndarray = field(default_factory=lambda: np.zeros(0))
    stable: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=_INT))
    own: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    born: np.ndarray = field(default_factory=lambda: np.zeros(0))
    name_ev: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    COLUMNS = (
        "ids", "sig", "sig_n", "visit", "emb", "emb_w", "hgt", "hgt_n", "stable", "own", "born",
        "name_ev",
    )  # fmt: skip

    def __len__(self) -> int:
        return len(self.ids)

    def __setstate__(self, state: dict[str, object]) -> None:
        # a checkpoint written before heights, or the visit's colours, were modelled
        self.__dict__.update(state)
        for name in ("hgt", "hgt_n"):
            self.__dict__.setdefault(name, np.zeros(len(self.ids)))
        self.__dict__.setdefault("visit", self.sig.copy())

    def copy(self) -> TrackModels:
        """An independent copy."""
        return TrackModels(**{name: getattr(self, name).copy() for name in self.COLUMNS})

    def rows(self, ids: np.ndarray) -> np.ndarray:
        """Row of each track id (``-1`` for ids without a row)."""
        if not len(self.ids):
            return np.full(len(ids), -1, dtype=_INT)
        order = np.argsort(self.ids, kind="stable")
        where, found = find_sorted(self.ids[order], ids)
        return np.where(found, order[where], -1)

    def add(self, ids: np.ndarray, born: float) -> None:
        """New rows for tracks ``ids``, each its own identity."""
        n = len(ids)
        self.ids = np.concatenate([self.ids, ids.astype(_INT)])
        self.sig = np.vstack([self.sig, np.zeros((n, self.sig.shape[1]))])
        self.sig_n = np.concatenate([self.sig_n, np.zeros(n)])
        self.visit = np.vstack([self.visit, np.zeros((n, self.visit.shape[1]))])
        self.emb = np.vstack([self.emb, np.zeros((n, self.emb.shape[1]))])
        self.emb_w = np.concatenate([self.emb_w, np.zeros(n)])
        self.hgt = np.concatenate([self.hgt, np.zeros(n)])
        self.hgt_n = np.concatenate([self.hgt_n, np.zeros(n)])
        self.stable = np.concatenate([self.stable, ids.astype(_INT)])
        self.own = np.concatenate([self.own, np.ones(n, dtype=bool)])
        self.born = np.concatenate([self.born, np.full(n, born)])
        self.name_ev = np.vstack([self.name_ev, np.zeros((n, self.name_ev.shape[1]))])

    def drop(self, rows: np.ndarray) -> None:
        """Remove ``rows``."""
        keep = np.ones(len(self), dtype=bool)
        keep[rows] = False
        for name in self.COLUMNS:
            setattr(self, name, getattr(self, name)[keep])

    def fit_dims(self, sig_dim: int, emb_dim: int) -> tuple[bool, bool]:
        """Size the models for signatures and embeddings of these lengths.

        A model takes the length of the first looks it sees; looks of another length
        (a second kind of detector) are ignored. Returns whether each kind fits.
        """
        if self.sig.shape[1] == 0 and sig_dim:
            self.sig = np.zeros((len(self), sig_dim))
            self.visit = np.zeros((len(self), sig_dim))
        if self.emb.shape[1] == 0 and emb_dim:
            self.emb = np.zeros((len(self), emb_dim))
        return self.sig.shape[1] == sig_dim > 0, self.emb.shape[1] == emb_dim > 0

    def learn_colour(
        self, rows: np.ndarray, sigs: np.ndarray, rate: float, visit_rate: float
    ) -> None:
        """Average clean signatures ``sigs`` into the colour models of ``rows``.

        ``rate`` for the model association uses, ``visit_rate`` for the visit's.
        """
        r = _weight(self.sig_n[rows], visit_rate, sigs.ndim)
        self.visit[rows] = (1.0 - r) * self.visit[rows] + r * sigs
        _average_into(self.sig, self.sig_n, rows, sigs, rate)

    def learn_height(self, rows: np.ndarray, heights: np.ndarray, rate: float) -> None:
        """Average clean detections' ``heights`` into the height models of ``rows``."""
        _average_into(self.hgt, self.hgt_n, rows, heights, rate)

    def learn_embedding(
        self, rows: np.ndarray, embs: np.ndarray, weights: np.ndarray, rate: float
    ) -> None:
        """Average embeddings into the models of ``rows``, each by its confidence."""
        total = self.emb_w[rows]
        r = (weights / np.maximum(total + weights, 1e-9)).clip(min=rate * weights)[:, None]
        mean = (1.0 - r) * self.emb[rows] + r * embs
        norm = np.linalg.norm(mean, axis=1, keepdims=True)
        self.emb[rows] = np.where(norm > 0, mean / np.maximum(norm, 1e-12), 0.0)
        self.emb_w[rows] = total + weights

    def exchange(self, a: int, b: int) -> None:
        """Rows ``a`` and ``b`` exchange everything but their track ids."""
        for name in self.COLUMNS[1:]:
            col = getattr(self, name)
            col[[a, b]] = col[[b, a]]

    def resize_names(self, mapping: np.ndarray) -> None:
        """Reorder the name evidence after a roster change.

        ``mapping[k]``: the old column of the new roster's name ``k`` (``-1``: new name).
        """
        out = np.zeros((len(self), len(mapping)))
        old = mapping >= 0
        if len(self) and old.any():
            out[:, old] = self.name_ev[:, mapping[old]]
        self.name_ev = out


def _average_into(
    model: np.ndarray, count: np.ndarray, rows: np.ndarray, values: np.ndarray, rate: float
) -> None:
    """Average ``values`` into ``model[rows]`` (in place), counting them in ``count``.

    The plain mean of the first ``1 / rate`` values, then an exponential average of rate
    ``rate`` (a model that follows slow changes).
    """
    n = count[rows]
    r = _weight(n, rate, values.ndim)
    model[rows] = (1.0 - r) * model[rows] + r * values
    count[rows] = n + 1.0


def _weight(count: np.ndarray, rate: float, ndim: int) -> np.ndarray:
    """Weight of the next value in a model averaging ``count`` values so far, at ``rate``.

    Shaped to broadcast over values of ``ndim`` dimensions (one row per value).
    """
    return np.maximum(rate, 1.0 / (count + 1.0)).reshape((-1,) + (1,) * (ndim - 1))


@dataclass(frozen=True)
class TrackLooks:
    """What a live track's models say of its person (what a roster entry captures).

    Parameters
    ----------
    signature : ndarray
        Colour model ``(B,)``, as association compares it: how the person looks now.
    observations : float
        The clean signatures it averages.
    embedding : ndarray
        Embedding model ``(D,)`` (zeros: none seen).
    height : float
        Height model, metres.
    height_observations : float
        The heights it averages (0: heights are not learned).
    """

    signature: np.ndarray
    observations: float
    embedding: np.ndarray
    height: float
    height_observations: float


@dataclass(frozen=True)
class PooledIdentity:
    """A confirmed person whose track was lost, waiting to be recognised again.

    Parameters
    ----------
    stable : int
        The identity.
    sig, sig_n, emb, emb_w : ndarray or float
        The lost track's looks (as in :class:`TrackModels`).
    xy : ndarray
        Where the person was last seen.
    lost_at : float
        When.
    name_ev : ndarray
        Its evidence for each registered name.
    impostor : float
        The highest model-to-model log-likelihood ratio between this person and anyone
        seen alive with them (someone else): how alike a stranger can look.
    impostor_id : int
        The track that ``impostor`` is of (-1: none).
    impostor_next : float
        The highest such ratio of anyone else: the impostor a track is held to when it
        is ``impostor_id`` itself (a person's new track, started before their old one
        was given up, is no stranger to them).
    hgt, hgt_n : float
        The lost track's height model and the heights it averages.
    born_at : float
        When the identity began: its first track's start, through links (``-inf``:
        unknown, taken as always there).
    """

    stable: int
    sig: np.ndarray
    sig_n: float
    emb: np.ndarray
    emb_w: float
    xy: np.ndarray
    lost_at: float
    name_ev: np.ndarray
    impostor: float = -np.inf
    impostor_id: int = -1
    impostor_next: float = -np.inf
    hgt: float = 0.0
    hgt_n: float = 0.0
    born_at: float = -np.inf


@dataclass(frozen=True)
class Side:
    """Looks compared on one side of a log-likelihood ratio: colours, embeddings, heights.

    ``sig_ok`` marks the colours that count; ``emb_w`` weighs each embedding (a
    detection's confidence, 1 for a model that has one, 0 for none); ``hgt_ok`` marks
    the heights that count (none by default).
    """

    sig: np.ndarray
    sig_ok: np.ndarray
    emb: np.ndarray
    emb_w: np.ndarray
    hgt: np.ndarray | None = None
    hgt_ok: np.ndarray | None = None

    def take(self, rows: np.ndarray) -> Side:
        """The looks of ``rows`` (in that order, repeats allowed)."""
        return Side(
            self.sig[rows], self.sig_ok[rows], self.emb[rows], self.emb_w[rows],
            None if self.hgt is None else self.hgt[rows],
            None if self.hgt_ok is None else self.hgt_ok[rows],
        )  # fmt: skip
