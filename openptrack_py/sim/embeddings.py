"""Simulated identity embeddings: a stand-in for a face (or body) recogniser.

No recognition model ships with the simulator, so it makes up what one would report.
Each person has a fixed random unit vector of :data:`EMBEDDING_DIMS` dimensions
(:class:`IdentityVectors`, drawn from the scenario seed and the person's id, the same
for every sensor). A detection of a person gets, as ``face``, that vector plus noise,
normalised, and a ``face_confidence``:

* only when the person **faces the sensor**: the angle between where they face (their
  heading: the direction they walk, or last walked) and the direction to the sensor is
  under :data:`MAX_ANGLE_DEG`, and the face is within :data:`MAX_DISTANCE_M`
  (OpenPTrack v2's face recognition needs frontal faces and drops those beyond 7.5 m;
  a 32-dimensional stand-in should not see further than the detector it replaces);
* **confidence** after the childcare tracking paper's face weight (Eq. 6,
  ``(1 - 2|theta|/pi) * exp(-L)``, theta the face angle, L the distance), with the
  distance in units of :data:`DISTANCE_SCALE_M` so that a frontal face at 1 m scores
  0.72 and at 5 m 0.19;
* **noise** per dimension with standard deviation ``0.03 + 0.25 * (1 - confidence)``: a
  confident embedding lies close to its person's vector (cosine about 0.99 at confidence
  1, 0.87 at 0.7, 0.55 near 0);
* with probability ``confusion_probability`` the embedding is drawn near **another**
  person's vector (one of the others present, uniformly; a stranger's when alone), with
  the confidence it would have had: the recogniser is sure, and wrong.

Random people have nearly orthogonal vectors (cosine about ``N(0, 1/sqrt(32))``).
"""

from __future__ import annotations

import math

import numpy as np

from openptrack_py.sim.people import Snapshot

EMBEDDING_DIMS = 32
"""Dimensions of a simulated embedding."""

MAX_ANGLE_DEG = 60.0
"""Faces turned further than this from the sensor are not recognised."""

MAX_DISTANCE_M = 5.0
"""Faces further than this from the sensor are not recognised."""

DISTANCE_SCALE_M = 3.0
"""Distance unit of the confidence's ``exp(-L)`` term, metres."""

_IDENTITY_KEY = 67
_STRANGER = 0


def face_confidence(angle_rad: np.ndarray, distance_m: np.ndarray) -> np.ndarray:
    """Confidence of an embedding of a face ``angle_rad`` off frontal at ``distance_m``.

    ``(1 - 2|angle|/pi) * exp(-distance / DISTANCE_SCALE_M)``, clipped to ``[0, 1]``.
    """
    angle = np.abs(np.asarray(angle_rad, dtype=float))
    frontal = np.clip(1.0 - 2.0 * angle / math.pi, 0.0, 1.0)
    return np.clip(frontal * np.exp(-np.asarray(distance_m) / DISTANCE_SCALE_M), 0.0, 1.0)


def noise_sigma(confidence: np.ndarray) -> np.ndarray:
    """Per-dimension noise of an embedding of ``confidence``."""
    return 0.03 + 0.25 * (1.0 - np.asarray(confidence, dtype=float))


class IdentityVectors:
    """Each person's fixed identity vector, from the scenario seed and the person's id.

    Parameters
    ----------
    seed : int
        The scenario seed.
    dims : int
        Dimensions.
    """

    def __init__(self, seed: int, dims: int = EMBEDDING_DIMS) -> None:
        self.seed = seed
        self.dims = dims
        self._cache: dict[int, np.ndarray] = {}

    def vector(self, person_id: int) -> np.ndarray:
        """The unit vector of ``person_id`` (0: a stranger, nobody in the scenario)."""
        v = self._cache.get(person_id)
        if v is None:
            draw = np.random.default_rng([self.seed, _IDENTITY_KEY, person_id])
            v = draw.normal(size=self.dims)
            v /= np.linalg.norm(v)
            self._cache[person_id] = v
        return v

    def vectors(self, person_ids: np.ndarray) -> np.ndarray:
        """``(n, dims)`` unit vectors of ``person_ids``."""
        if len(person_ids) == 0:
            return np.zeros((0, self.dims))
        return np.stack([self.vector(int(i)) for i in person_ids])


class FaceRecogniser:
    """What a face recogniser beside one sensor would report of the people it detects.

    Parameters
    ----------
    identities : IdentityVectors
        Everyone's identity vector (shared by every sensor of a scenario).
    origin : ndarray
        The sensor's position in the world, metres.
    rng : numpy.random.Generator
        The recogniser's own randomness (noise and confusions).
    confusion_probability : float
        Probability that an embedding is drawn near another person's vector.
    """

    def __init__(
        self,
        identities: IdentityVectors,
        origin: np.ndarray,
        rng: np.random.Generator,
        confusion_probability: float = 0.02,
    ) -> None:
        self.identities = identities
        self.origin = np.asarray(origin, dtype=float)
        self.rng = rng
        self.confusion_probability = confusion_probability

    def visible(self, snap: Snapshot, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Which of the people in ``rows`` show a recognisable face, and its confidence.

        Returns
        -------
        shown : ndarray of bool
            Facing the sensor within :data:`MAX_ANGLE_DEG` and :data:`MAX_DISTANCE_M`.
        confidence : ndarray
            :func:`face_confidence` (0 where not shown).
        """
        rows = np.asarray(rows, dtype=int)
        if len(rows) == 0:
            return np.zeros(0, dtype=bool), np.zeros(0)
        head = np.column_stack([snap.pos[rows], 0.93 * snap.height[rows]])
        to_sensor = self.origin[:2] - snap.pos[rows]
        floor = np.linalg.norm(to_sensor, axis=1)
        facing = snap.facing()[rows]
        cos = np.einsum("ij,ij->i", facing, to_sensor) / np.maximum(floor, 1e-9)
        angle = np.arccos(np.clip(cos, -1.0, 1.0))
        distance = np.linalg.norm(head - self.origin, axis=1)
        shown = (angle < math.radians(MAX_ANGLE_DEG)) & (distance <= MAX_DISTANCE_M)
        return shown, np.where(shown, face_confidence(angle, distance), 0.0)

    def embed(
        self, snap: Snapshot, rows: np.ndarray
    ) -> list[tuple[tuple[float, ...], float] | None]:
        """Per row of ``snap`` (negative: not a person), ``(face, confidence)`` or None.

        Draws from :attr:`rng` only for the faces it reports.
        """
        rows = np.asarray(rows, dtype=int)
        out: list[tuple[tuple[float, ...], float] | None] = [None] * len(rows)
        people = np.flatnonzero(rows >= 0)
        shown, confidence = self.visible(snap, rows[people])
        chosen = people[shown]
        if not len(chosen):
            return out
        conf = confidence[shown]
        k = len(chosen)
        ids = snap.ids[rows[chosen]].astype(int)
        confused = self.rng.random(k) < self.confusion_probability
        pick = self.rng.random(k)
        noise = self.rng.normal(size=(k, self.identities.dims))
        target = ids.copy()
        for j in np.flatnonzero(confused):
            others = snap.ids[snap.ids != ids[j]]
            target[j] = int(others[int(pick[j] * len(others))]) if len(others) else _STRANGER
        vec = self.identities.vectors(target) + noise * noise_sigma(conf)[:, None]
        vec /= np.linalg.norm(vec, axis=1, keepdims=True)
        vec = np.round(vec, 5)
        for j, i in enumerate(chosen.tolist()):
            out[i] = (tuple(vec[j].tolist()), round(float(conf[j]), 4))
        return out
