"""The tracker's state as arrays: the detections of a step and the table of tracks.

Both are column-oriented (one numpy array per field, one row per detection or track)
so that every step costs a handful of vectorised operations, whatever the number of
people. :class:`TrackTable` is the per-track state that the tracker's late-batch replay
restores; a column added here is restored with the rest.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from openptrack_py.messages.detection import Detection, DetectionBatch

HISTORY = 48
"""Past positions kept per track (for the velocity measurement)."""
HISTORY_SPACING_S = 0.04
"""Least time between two remembered positions of a track."""
SENSOR_SLOTS = 16
"""Sensors whose last detection of each track is remembered one by one."""


def sensor_slot(sensor_index: int) -> int:
    """The column of ``TrackTable.sensor_hit_t`` of a sensor (by index)."""
    return min(sensor_index, SENSOR_SLOTS - 1)


def _common_length(vectors: list[tuple | None]) -> int:
    """The most frequent length among the vectors present (0 when none)."""
    lengths = [len(v) for v in vectors if v]
    return max(set(lengths), key=lengths.count) if lengths else 0


def _unit_rows(vectors: list[tuple | None], dim: int, norm: str) -> tuple[np.ndarray, np.ndarray]:
    """Rows of the vectors of length ``dim`` scaled to unit ``norm`` ("l1" or "l2")."""
    out = np.zeros((len(vectors), dim))
    ok = np.array([bool(v) and len(v) == dim for v in vectors], dtype=bool)
    if ok.any():
        rows = np.array([v for v, good in zip(vectors, ok, strict=True) if good], dtype=float)
        scale = np.abs(rows).sum(axis=1) if norm == "l1" else np.linalg.norm(rows, axis=1)
        good = scale > 0
        rows[good] /= scale[good, None]
        out[ok] = rows
        ok[np.flatnonzero(ok)[~good]] = False
    return out, ok


@dataclass(frozen=True)
class Looks:
    """What a batch's detections look like: colour signatures and identity embeddings.

    Parameters
    ----------
    signature : ndarray
        ``(M, B)`` colour signatures scaled to sum to 1 (zeros where there is none).
    has_signature : ndarray of bool
        Whether each detection has a signature of the batch's common length.
    clean : ndarray of bool
        Whether each detection's image box is free of any nearer detection's box: a
        half-hidden person's colours are mixed with those of the one in front.
    embedding : ndarray
        ``(M, D)`` identity embeddings (``face``) scaled to unit length (zeros: none).
    embedding_weight : ndarray
        Confidence of each embedding (``face_confidence``, 1 when not given; 0: none).
    """

    signature: np.ndarray
    has_signature: np.ndarray
    clean: np.ndarray
    embedding: np.ndarray
    embedding_weight: np.ndarray

    def subset(self, rows: np.ndarray) -> Looks:
        """The looks of the detections at ``rows``."""
        return Looks(
            self.signature[rows], self.has_signature[rows], self.clean[rows],
            self.embedding[rows], self.embedding_weight[rows],
        )  # fmt: skip

    @classmethod
    def of(cls, detections: list[Detection]) -> Looks:
        """The looks of ``detections`` (one batch)."""
        sigs = [d.appearance for d in detections]
        signature, has_signature = _unit_rows(sigs, _common_length(sigs), "l1")
        faces = [d.face for d in detections]
        embedding, has_face = _unit_rows(faces, _common_length(faces), "l2")
        weight = np.array(
            [_face_weight(d) if ok else 0.0 for d, ok in zip(detections, has_face, strict=True)]
        )
        return cls(signature, has_signature, _unoccluded(detections), embedding, weight)


def _face_weight(detection: Detection) -> float:
    """Confidence of a detection's embedding (1 when the detector gives none)."""
    conf = getattr(detection, "face_confidence", None)
    return 1.0 if conf is None else float(conf)


def _unoccluded(detections: list[Detection]) -> np.ndarray:
    """Whether each detection's box overlaps no box of a nearer detection."""
    n = len(detections)
    clean = np.ones(n, dtype=bool)
    boxed = [i for i, d in enumerate(detections) if d.bbox is not None]
    if len(boxed) < 2:
        return clean
    b = np.array([detections[i].bbox for i in boxed], dtype=float)
    dist = np.array([detections[i].distance for i in boxed])
    u0, v0, u1, v1 = b[:, 0], b[:, 1], b[:, 0] + b[:, 2], b[:, 1] + b[:, 3]
    overlap = (np.minimum(u1[:, None], u1[None, :]) > np.maximum(u0[:, None], u0[None, :])) & (
        np.minimum(v1[:, None], v1[None, :]) > np.maximum(v0[:, None], v0[None, :])
    )
    np.fill_diagonal(overlap, False)
    behind = (overlap & (dist[None, :] < dist[:, None])).any(axis=1)
    clean[np.array(boxed)[behind]] = False
    return clean


@dataclass(frozen=True)
class DetectionArrays:
    """The detections of one batch that the tracker uses, as arrays.

    Parameters
    ----------
    index : ndarray
        Position of each kept detection in the batch.
    xy, z, height, confidence, distance : ndarray
        Per-detection values.
    sensor_id : str
        The sensor of the batch.
    seq : int
        The batch's sequence number.
    looks : Looks or None
        Colour signatures and identity embeddings, when an identity role asked for them.
    """

    index: np.ndarray
    xy: np.ndarray
    z: np.ndarray
    height: np.ndarray
    confidence: np.ndarray
    distance: np.ndarray
    sensor_id: str = ""
    seq: int = -1
    looks: Looks | None = None

    def __len__(self) -> int:
        return len(self.index)

    def subset(self, rows: np.ndarray) -> DetectionArrays:
        """The detections at ``rows`` (indices or a mask), in that order."""
        return DetectionArrays(
            index=self.index[rows],
            xy=self.xy[rows],
            z=self.z[rows],
            height=self.height[rows],
            confidence=self.confidence[rows],
            distance=self.distance[rows],
            sensor_id=self.sensor_id,
            seq=self.seq,
            looks=None if self.looks is None else self.looks.subset(rows),
        )

    @classmethod
    def from_batch(
        cls, batch: DetectionBatch, min_confidence: float, looks: bool = False
    ) -> DetectionArrays:
        """Arrays of the batch's detections at least ``min_confidence`` confident.

        ``looks``: also their :class:`Looks` (occlusion judged among all the batch's
        detections).
        """
        kept = [(i, d) for i, d in enumerate(batch.detections) if d.confidence >= min_confidence]
        seen = None
        if looks:
            seen = Looks.of(list(batch.detections)).subset(
                np.array([i for i, _ in kept], dtype=int)
            )
        if not kept:
            empty = np.zeros(0)
            return cls(
                np.zeros(0, dtype=int), np.zeros((0, 2)), empty, empty, empty, empty,
                batch.sensor_id, batch.seq, seen,
            )  # fmt: skip
        rows = np.array([(d.x, d.y, d.z, d.height, d.confidence, d.distance) for _, d in kept])
        return cls(
            index=np.array([i for i, _ in kept]),
            xy=rows[:, 0:2],
            z=rows[:, 2],
            height=rows[:, 3],
            confidence=rows[:, 4],
            distance=rows[:, 5],
            sensor_id=batch.sensor_id,
            seq=batch.seq,
            looks=seen,
        )


@dataclass
class TrackTable:
    """Every track's state, as parallel arrays (one row per track).

    Parameters
    ----------
    ids : ndarray of int
        Track ids, never reused.
    x, cov : ndarray
        UKF state ``[x, y, vx, vy]`` and its covariance.
    z, height : ndarray
        Smoothed centroid height and person height, metres.
    confidence : ndarray
        Exponential average of the detector confidence of the track's detections.
    first_seen, last_seen : ndarray
        Time of the first detection, and of the last confident one.
    hits : ndarray of int
        Confident detections so far.
    confirmed : ndarray of bool
        Whether the track is confirmed (published).
    hist_t, hist_xy : ndarray
        Remembered past positions (for the velocity measurement).
    support : ndarray
        Share of the recent frames of the sensors that should see the track that did
        detect it (exponential average): how well the evidence holds up.
    birth_xy : ndarray
        Mean position of the track's first detections: where it started.
    birth_n : ndarray of int
        Detections averaged into ``birth_xy`` so far.
    recent_xy : ndarray
        Exponential average of the positions of the track's recent detections (where
        the evidence says it is, unlike the filter's prediction while unseen).
    last_sensor : ndarray of int
        Index of the sensor of the track's last detection.
    multi_t : ndarray
        Last time the track's detections came from two different sensors in a row.
    evidence : ndarray
        Log-likelihood ratio of "a person" against "a static false positive" from the
        track's detections and misses in the frames of the sensors that should see it
        (a sequential probability ratio test; see ``lifecycle``).
    sensor_hit_t : ndarray
        ``(n, SENSOR_SLOTS)`` last time each sensor (by index; later sensors share the
        last slot) detected the track; ``-inf`` for never.
    sensor_evidence : ndarray
        ``(n, SENSOR_SLOTS)`` each sensor's own part of ``evidence`` for a tentative
        track, counting, beside confirmed tracks, only the frames in which the sensor
        detected each of them too (see ``lifecycle``); kept only when asked for.
    sensor_support : ndarray
        ``(n, SENSOR_SLOTS)`` each sensor's own running hit rate of a confirmed track,
        over the sensor's frames that can tell: beside other confirmed tracks only
        those that detected each of them too, away from others every frame (see
        ``bookkeeping.update_support``); kept only when asked for.
    """

    ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    x: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    cov: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    z: np.ndarray = field(default_factory=lambda: np.zeros(0))
    height: np.ndarray = field(default_factory=lambda: np.zeros(0))
    confidence: np.ndarray = field(default_factory=lambda: np.zeros(0))
    first_seen: np.ndarray = field(default_factory=lambda: np.zeros(0))
    last_seen: np.ndarray = field(default_factory=lambda: np.zeros(0))
    hits: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    confirmed: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    hist_t: np.ndarray = field(default_factory=lambda: np.zeros((0, HISTORY)))
    hist_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, HISTORY, 2)))
    support: np.ndarray = field(default_factory=lambda: np.zeros(0))
    birth_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    birth_n: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    recent_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    last_sensor: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    multi_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    evidence: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sensor_hit_t: np.ndarray = field(default_factory=lambda: np.zeros((0, SENSOR_SLOTS)))
    sensor_evidence: np.ndarray = field(default_factory=lambda: np.zeros((0, SENSOR_SLOTS)))
    sensor_support: np.ndarray = field(default_factory=lambda: np.zeros((0, SENSOR_SLOTS)))

    COLUMNS = (
        "ids", "x", "cov", "z", "height", "confidence", "first_seen", "last_seen", "hits",
        "confirmed", "hist_t", "hist_xy", "support", "birth_xy", "birth_n", "recent_xy",
        "last_sensor", "multi_t", "evidence", "sensor_hit_t", "sensor_evidence",
        "sensor_support",
    )  # fmt: skip

    def __setstate__(self, state: dict[str, np.ndarray]) -> None:
        # a table pickled (checkpointed) before the per-sensor columns were kept
        self.__dict__.update(state)
        for name in ("sensor_evidence", "sensor_support"):
            if name not in state:
                setattr(self, name, np.zeros((len(self.ids), SENSOR_SLOTS)))

    def __len__(self) -> int:
        return len(self.ids)

    def keep(self, mask: np.ndarray) -> None:
        """Drop the rows where ``mask`` is False."""
        for name in self.COLUMNS:
            setattr(self, name, getattr(self, name)[mask])

    def copy(self) -> TrackTable:
        """An independent copy."""
        return TrackTable(**{name: getattr(self, name).copy() for name in self.COLUMNS})

    def append(self, **rows: np.ndarray) -> None:
        """Add rows (one array per column, same length)."""
        for name in self.COLUMNS:
            setattr(self, name, np.concatenate([getattr(self, name), rows[name]]))
