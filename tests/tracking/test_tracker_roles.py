"""The tracker composed from stub roles: it depends only on the role interfaces.

And per-track state kept by a role survives a late-batch replay when the role exposes it
(``Stateful``), while a role that hides it demonstrably does not.
"""

from __future__ import annotations

import numpy as np
import pytest

from openptrack_py.tracking import (
    Associator,
    Deleter,
    Gater,
    IdentityModel,
    Initiator,
    MeasurementModel,
    Merger,
    MotionModel,
    NullIdentity,
    SensorModel,
    Stateful,
    TrackingPipeline,
    build_tracker,
)
from tests.tracking.conftest import CountingIdentity, ForgetfulIdentity, stub_tracker
from tests.tracking.helpers import FRAME, T0, det, make_batch

PEOPLE = ((1.0, 1.0), (3.0, 2.0))


def _two_still_people(tracker, frames: int = 10) -> None:
    for k in range(frames):
        tracker.step(make_batch(T0 + k * FRAME, [det(*p) for p in PEOPLE], seq=k))


def test_a_tracker_of_stubs_tracks_two_people() -> None:
    tracker = stub_tracker()
    _two_still_people(tracker)
    out = tracker.output(tracker.time)
    assert sorted(t.id for t in out.tracks) == [1, 2]
    got = sorted((round(t.x, 6), round(t.y, 6)) for t in out.tracks)
    assert got == sorted(PEOPLE)


def test_stub_roles_satisfy_the_role_protocols(stub_roles: dict[str, object]) -> None:
    protocols = {
        "motion": MotionModel,
        "measurement": MeasurementModel,
        "gater": Gater,
        "associator": Associator,
        "initiator": Initiator,
        "deleter": Deleter,
        "sensors": SensorModel,
        "merger": Merger,
    }
    for name, role in stub_roles.items():
        for member in ("fx", "noise", "hx", "pair_measurements", "position_noise", "gate",
                       "associate", "initiate", "confirm", "delete", "correct", "noise_scale",
                       "covers", "learn", "observe", "merge"):  # fmt: skip
            if hasattr(protocols[name], member):
                assert callable(getattr(role, member)), (name, member)


def test_default_roles_are_the_configured_ones() -> None:
    tracker = build_tracker()
    assert isinstance(tracker.identity, NullIdentity)
    # what is learned about sensors, and the pairs waiting to merge, survive replays
    stateful = [role for role in tracker.roles if isinstance(role, Stateful)]
    assert stateful == [tracker.sensors, tracker.merger]
    identity: IdentityModel = tracker.identity
    assert identity.labels(np.array([3, 5])) == ([None, None], [None, None])


def test_identity_annotations_reach_the_output() -> None:
    tracker = stub_tracker(CountingIdentity())
    _two_still_people(tracker, frames=4)
    out = tracker.output(tracker.time)
    assert {(t.stable_id, t.identity) for t in out.tracks} == {(10001, "seen4"), (10002, "seen4")}


def _stream() -> tuple[list[tuple[object, float]], object]:
    """Two sensors see two still people; sensor b's frame 20 arrives 0.3 s late."""
    items = []
    late = None
    for k in range(40):
        for sensor, phase in (("a", 0.0), ("b", 0.016)):
            stamp = T0 + k * FRAME + phase
            arrival = stamp + 0.01 + (0.3 if sensor == "b" and k == 20 else 0.0)
            batch = make_batch(stamp, [det(*p) for p in PEOPLE], sensor=sensor, seq=k)
            items.append((batch, arrival))
            if sensor == "b" and k == 20:
                late = batch
    items.sort(key=lambda item: item[1])
    return items, late


def _run(identity: object, *, in_capture_order: bool) -> tuple[TrackingPipeline, list]:
    items, _ = _stream()
    if in_capture_order:
        items = sorted(items, key=lambda item: item[0].stamp)
    pipe = TrackingPipeline(stub_tracker(identity), window_s=0.0, clock_correction="none")
    outputs = []
    for batch, arrival in items:
        outputs += [tracks for _, tracks in pipe.push(batch, arrival)]
    return pipe, outputs


@pytest.mark.parametrize("role", [CountingIdentity, ForgetfulIdentity], ids=["stateful", "hidden"])
def test_role_state_survives_a_late_batch_replay(role: type) -> None:
    late_pipe, late_out = _run(role(), in_capture_order=False)
    ontime_pipe, ontime_out = _run(role(), in_capture_order=True)
    assert late_pipe.tracker.counters["late_applied"] == 1
    assert late_pipe.tracker.counters["replayed_steps"] > 0
    np.testing.assert_allclose(late_pipe.tracker.table.x, ontime_pipe.tracker.table.x, atol=1e-12)
    same = late_pipe.tracker.identity.counts == ontime_pipe.tracker.identity.counts
    names = {t.identity for t in late_out[-1].tracks}
    if role is CountingIdentity:
        assert same, "a Stateful role must come back from a replay exactly"
        assert names == {t.identity for t in ontime_out[-1].tracks} == {"seen80"}
    else:
        # the control: state hidden from the snapshot counts replayed steps twice
        assert not same
