"""Tests for openptrack_py.sim.embeddings: simulated identity embeddings on detections."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from openptrack_py.config import NetworkConfig, Pose, SensorConfig, SimConfig
from openptrack_py.errors import ConfigError
from openptrack_py.sensor_types import SENSOR_TYPES
from openptrack_py.sim import SensorFrame, SensorModel, SensorSpec, Simulator, build_scenario
from openptrack_py.sim.embeddings import (
    EMBEDDING_DIMS,
    MAX_DISTANCE_M,
    FaceRecogniser,
    IdentityVectors,
    face_confidence,
)
from openptrack_py.sim.live import scenario_from_network
from openptrack_py.sim.profiles import IDEAL, REALISTIC, resolve_profile
from openptrack_py.sim.world import Room, Snapshot
from tests.conftest import people_snapshot

SENSOR = Pose(x=0.0, y=5.0, z=2.2, yaw_deg=0.0, pitch_deg=12.0)
TOWARDS, AWAY, SIDEWAYS = math.pi, 0.0, math.pi / 2  # headings relative to the sensor


WITH_EMBEDDINGS = IDEAL.with_embeddings()


def _model(profile=WITH_EMBEDDINGS, seed: int = 0, **spec: object) -> SensorModel:
    options = {"miss_probability": 0.0, "clutter_per_frame": 0.0, **spec}
    return SensorModel(
        SensorSpec(id="s", type=SENSOR_TYPES["kinect2"], pose=SENSOR, rate_hz=30.0, **options),  # type: ignore[arg-type]
        Room(20.0, 10.0),
        np.random.default_rng(seed),
        profile=profile,
        identities=IdentityVectors(11),
    )


def _people(rows: list[tuple[float, float, float]]) -> Snapshot:
    """People at ``(x, y)`` facing ``heading``; adults 1.75 m."""
    snap = people_snapshot([(x, y, 1.75, 0.2, 0.0, 0.0) for x, y, _ in rows])
    return dataclasses.replace(snap, heading=np.array([h for _, _, h in rows]))


def _faces(model: SensorModel, snap: Snapshot, frames: int) -> dict[int, list[tuple]]:
    out: dict[int, list[tuple]] = {int(i): [] for i in snap.ids}
    for _ in range(frames):
        obs = model.observe(snap)
        for det, pid in zip(obs.detections, obs.person_ids, strict=True):
            if pid and det.face is not None:
                out[pid].append((np.array(det.face), det.face_confidence))
    return out


def test_confidence_falls_with_angle_and_distance() -> None:
    assert face_confidence(0.0, 0.0) == pytest.approx(1.0)
    assert face_confidence(0.0, 1.0) == pytest.approx(math.exp(-1 / 3))
    near, far = face_confidence(0.0, np.array([1.0, 4.0]))
    front, turned = face_confidence(np.radians([0.0, 50.0]), 2.0)
    assert near > far and front > turned > 0.0
    assert face_confidence(math.pi / 2, 1.0) == 0.0
    assert face_confidence(-0.5, 2.0) == face_confidence(0.5, 2.0)


def test_identity_vectors_are_fixed_unit_vectors_per_scenario_seed() -> None:
    a, b, other = IdentityVectors(3), IdentityVectors(3), IdentityVectors(4)
    assert a.vector(5).shape == (EMBEDDING_DIMS,)
    assert np.linalg.norm(a.vector(5)) == pytest.approx(1.0)
    assert np.array_equal(a.vector(5), b.vector(5))
    assert not np.allclose(a.vector(5), other.vector(5))
    cos = a.vectors(np.arange(1, 41)) @ a.vectors(np.arange(1, 41)).T
    off = cos[~np.eye(40, dtype=bool)]
    assert np.abs(off).mean() < 0.2 and np.abs(off).max() < 0.7  # nearly orthogonal


def test_faces_only_of_people_facing_the_sensor_within_reach() -> None:
    snap = _people(
        [
            (2.0, 5.0, TOWARDS),  # 1: frontal, 2 m: a face
            (2.5, 3.6, AWAY),  # 2: back to the sensor
            (7.0, 5.0, TOWARDS),  # 3: frontal but 7 m away
            (3.0, 6.5, SIDEWAYS),  # 4: profile (about 60-90 degrees off)
            (3.5, 4.2, TOWARDS + 0.5),  # 5: turned 30 degrees: a face, less confident
        ]
    )
    faces = _faces(_model(), snap, 20)
    assert len(faces[1]) == len(faces[5]) == 20
    assert faces[2] == faces[3] == faces[4] == []
    conf1 = np.array([c for _, c in faces[1]])
    conf5 = np.array([c for _, c in faces[5]])
    assert np.all((conf1 > 0.3) & (conf1 <= 1.0)) and conf1.min() > conf5.max()
    for vec, _ in faces[1]:
        assert len(vec) == EMBEDDING_DIMS and np.linalg.norm(vec) == pytest.approx(1, abs=1e-4)


def test_standing_people_face_where_they_last_walked() -> None:
    """Without a heading the snapshot falls back on the velocity."""
    snap = people_snapshot(
        [(2.0, 5.0, 1.75, 0.2, 0, 0), (2.0, 3.5, 1.75, 0.2, 0, 0)],
        vel=np.array([[-1.0, 0.0], [1.0, 0.0]]),  # towards the sensor, away from it
    )
    faces = _faces(_model(), snap, 5)
    assert len(faces[1]) == 5 and faces[2] == []


def test_one_persons_embeddings_agree_and_differ_from_anothers() -> None:
    snap = _people([(2.0, 5.0, TOWARDS), (2.5, 3.8, TOWARDS), (4.5, 6.0, TOWARDS)])
    model = _model(profile=IDEAL.with_embeddings(confusion=0.0))
    faces = _faces(model, snap, 60)
    vectors = {pid: np.array([v for v, _ in rows]) for pid, rows in faces.items()}
    truth = IdentityVectors(11)
    same = {}
    for pid, vec in vectors.items():
        assert len(vec) == 60
        same[pid] = (vec[:30] @ vec[30:].T).mean()
    # near the person's identity; the nearest and most frontal nearest of all
    assert (vectors[1] @ truth.vector(1)).mean() > 0.7 and same[1] > 0.5
    assert min(same.values()) > 0.3
    for a, b in ((1, 2), (1, 3), (2, 3)):
        assert np.abs(vectors[a] @ vectors[b].T).mean() < 0.35
    # noisier when less confident: the far person's embeddings scatter more
    near = (vectors[1] @ truth.vector(1)).mean()
    far = (vectors[3] @ truth.vector(3)).mean()
    assert near > far


@pytest.mark.parametrize("rate", [0.02, 0.2])
def test_confusions_happen_at_the_configured_rate(rate: float) -> None:
    ids = IdentityVectors(2)
    snap = _people([(2.0, 5.0, TOWARDS), (2.0, 4.0, TOWARDS), (2.0, 6.0, TOWARDS)])
    recogniser = FaceRecogniser(ids, np.array([0.0, 5.0, 2.2]), np.random.default_rng(1), rate)
    rows = np.array([0, 1, 2])
    wrong = total = 0
    for _ in range(1500):
        for row, out in enumerate(recogniser.embed(snap, rows)):
            assert out is not None
            vec = np.array(out[0])
            scores = ids.vectors(snap.ids) @ vec
            wrong += int(np.argmax(scores) != row)
            total += 1
    assert wrong / total == pytest.approx(rate, abs=max(0.006, rate * 0.2))


def test_clutter_and_misses_get_no_face_and_nothing_else_changes() -> None:
    snap = _people([(2.0, 5.0, TOWARDS), (3.0, 4.0, TOWARDS)])
    plain = _model(profile=IDEAL, seed=4, clutter_per_frame=2.0, miss_probability=0.2)
    faces = _model(seed=4, clutter_per_frame=2.0, miss_probability=0.2)
    seen = 0
    for _ in range(40):
        a, b = plain.observe(snap), faces.observe(snap)
        assert a.person_ids == b.person_ids
        for da, db, pid in zip(a.detections, b.detections, a.person_ids, strict=True):
            assert da == dataclasses.replace(db, face=None, face_confidence=None)
            assert da.face is None
            if pid == 0:
                assert db.face is None and db.face_confidence is None
            else:
                seen += db.face is not None
    assert seen > 40


def test_a_scenario_with_embeddings_changes_only_the_faces() -> None:
    """Embeddings draw from generators of their own: every other bit stays the same."""
    runs = [
        [
            ev
            for ev in Simulator(build_scenario("crowd", seed=2, duration_s=4.0, **kw)).events()
            if isinstance(ev, SensorFrame)
        ]
        for kw in ({"profile": "realistic"}, {"profile": "realistic+embeddings"})
    ]
    faces = 0
    for a, b in zip(*runs, strict=True):
        assert (a.time, a.person_ids, a.batch.seq) == (b.time, b.person_ids, b.batch.seq)
        for da, db in zip(a.batch.detections, b.batch.detections, strict=True):
            assert da == dataclasses.replace(db, face=None, face_confidence=None)
            faces += db.face is not None
    assert faces > 20
    # every sensor agrees on a person's identity: the vectors come from the scenario seed
    by_person: dict[int, list[np.ndarray]] = {}
    for ev in runs[1]:
        for det, pid in zip(ev.batch.detections, ev.person_ids, strict=True):
            if pid and det.face is not None and det.face_confidence > 0.3:
                by_person.setdefault(pid, []).append(np.array(det.face))
    truth = IdentityVectors(2)
    for pid, vecs in by_person.items():
        assert (np.array(vecs) @ truth.vector(pid)).mean() > 0.6


def test_embeddings_are_a_profile_option() -> None:
    for profile in (IDEAL, REALISTIC):
        assert not profile.embeddings
    on = resolve_profile("realistic+embeddings")
    assert on.embeddings and on.name == "realistic+embeddings"
    assert dataclasses.replace(on, embeddings=False, name="realistic") == REALISTIC
    assert on.with_embeddings(False) == REALISTIC
    assert on.with_embeddings().name == "realistic+embeddings"
    assert build_scenario("crowd", embeddings=True).profile == IDEAL.with_embeddings()
    assert build_scenario("crowd", profile="harsh", embeddings=True).profile.embeddings
    with pytest.raises(ConfigError, match="embedding_confusion_probability must be in"):
        REALISTIC.with_embeddings(confusion=1.5)
    with pytest.raises(ConfigError, match=r"embeddings must be true or false \(1\)"):
        dataclasses.replace(REALISTIC, embeddings=1)
    with pytest.raises(ConfigError, match=r"unknown 'realistic\+faces'"):
        resolve_profile("realistic+faces")
    sensors = [SensorConfig(id="a", pose=SENSOR)]
    cfg = NetworkConfig(sensors=sensors, sim=SimConfig(scenario="crowd", embeddings=True))
    assert scenario_from_network(cfg).profile == REALISTIC.with_embeddings()
    assert SimConfig().embeddings is False


def test_faces_are_within_the_recognisers_reach() -> None:
    ids = IdentityVectors(0)
    recogniser = FaceRecogniser(ids, np.array([0.0, 5.0, 2.2]), np.random.default_rng(0))
    xs = np.linspace(0.6, 8.0, 40)
    snap = _people([(x, 5.0, TOWARDS) for x in xs])
    shown, conf = recogniser.visible(snap, np.arange(len(xs)))
    head = np.hypot(xs, 2.2 - 0.93 * 1.75)
    assert np.array_equal(shown, head <= MAX_DISTANCE_M)
    assert np.all(np.diff(conf[shown]) < 0)  # further, less confident
