"""Key expressions, and the Bus contract honoured by both MemoryBus and ZenohBus."""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest
import zenoh
from hypothesis import given, settings
from hypothesis import strategies as st

from openptrack_py.config import ZenohConfig
from openptrack_py.transport import (
    MemoryBus,
    MemoryNetwork,
    SiteKeys,
    key_matches,
    wait_for_subscribers,
)
from openptrack_py.transport.keys import validate_key
from openptrack_py.transport.zenoh_bus import ZenohBus, build_zenoh_config
from tests.conftest import wait_for

# ----------------------------------------------------------------- key expressions

chunks = st.sampled_from(["opt", "default", "detections", "k1", "tracks", "a", "b"])
keys = st.lists(chunks, min_size=1, max_size=5).map("/".join)
expr_chunks = st.one_of(chunks, st.just("*"), st.just("**"))


def _canonical(parts: list[str]) -> str:
    # Zenoh's canonical form has no '**/**' run and no '**/*' (it is '*/**').
    out: list[str] = []
    for p in parts:
        if p == "**" and out and out[-1] == "**":
            continue
        if p == "*" and out and out[-1] == "**":
            out[-1] = "*"
            out.append("**")
            continue
        out.append(p)
    return "/".join(out)


exprs = st.lists(expr_chunks, min_size=1, max_size=5).map(_canonical)


@settings(max_examples=400, deadline=None)
@given(expr=exprs, key=keys)
def test_key_matching_agrees_with_zenoh(expr: str, key: str) -> None:
    assert key_matches(expr, key) == zenoh.KeyExpr(expr).includes(zenoh.KeyExpr(key))


@pytest.mark.parametrize(
    ("expr", "key", "expected"),
    [
        ("opt/default/detections/*", "opt/default/detections/k1", True),
        ("opt/default/detections/*", "opt/default/detections", False),
        ("opt/default/detections/**", "opt/default/detections", True),
        ("opt/*/tracks", "opt/lab/tracks", True),
        ("opt/*/tracks", "opt/lab/tracks/smoothed", False),
        ("**/smoothed", "opt/lab/tracks/smoothed", True),
    ],
    ids=["star", "star-needs-chunk", "double-star-empty", "mid-star", "star-one-chunk", "lead"],
)
def test_key_matching_examples(expr: str, key: str, expected: bool) -> None:
    assert key_matches(expr, key) is expected


def test_site_keys_follow_the_design() -> None:
    k = SiteKeys("lab")
    assert k.detections("k1") == "opt/lab/detections/k1"
    assert k.tracks == "opt/lab/tracks"
    assert k.tracks_smoothed == "opt/lab/tracks/smoothed"
    assert k.calibration("k1") == "opt/lab/calibration/k1"
    assert k.config("tracker") == "opt/lab/config/tracker"
    assert k.alive("sim") == "opt/lab/alive/sim"
    assert k.stats("sim") == "opt/lab/stats/sim"
    assert k.ground_truth == "opt/lab/ground_truth"


@pytest.mark.parametrize("bad", ["", "/a", "a/", "a//b", "a/*", "a/$x", "a/b?c"], ids=str)
def test_invalid_concrete_keys_are_refused(bad: str) -> None:
    with pytest.raises(ValueError, match="key"):
        validate_key(bad)


def test_zenoh_config_translation() -> None:
    cfg = ZenohConfig(hub="tcp/127.0.0.1:17000", listen=["tcp/127.0.0.1:0"], connect=[])
    node = build_zenoh_config(cfg)
    assert '"tcp/127.0.0.1:17000"' in node.get_json("connect/endpoints")
    assert node.get_json("scouting/multicast/enabled") == "false"
    assert node.get_json("mode") == '"peer"'
    hub = build_zenoh_config(cfg, as_hub=True)
    assert '"tcp/127.0.0.1:17000"' in hub.get_json("listen/endpoints")
    assert "17000" not in hub.get_json("connect/endpoints")
    # a peer told to listen on the hub (-l) is the hub: it does not connect to itself
    on_hub = cfg.model_copy(update={"listen": ["tcp/127.0.0.1:17000"]})
    assert "17000" not in build_zenoh_config(on_hub).get_json("connect/endpoints")
    client = on_hub.model_copy(update={"mode": "client"})  # a client never listens
    assert "17000" in build_zenoh_config(client).get_json("connect/endpoints")


# -------------------------------------------------------------------- bus contract


@pytest.fixture(params=["memory", "zenoh"])
def bus_pair(request: pytest.FixtureRequest, zenoh_cfg: ZenohConfig) -> Iterator[tuple]:
    """Two buses that see each other (two 'processes'), plus the hub if any."""
    if request.param == "memory":
        net = MemoryNetwork()
        a, b = MemoryBus(net), MemoryBus(net)
        yield a, b
        a.close()
        b.close()
        return
    hub = ZenohBus(zenoh_cfg, as_hub=True)
    a, b = ZenohBus(zenoh_cfg), ZenohBus(zenoh_cfg)
    yield a, b
    for bus in (a, b, hub):
        bus.close()


def test_publish_subscribe_in_order(bus_pair: tuple) -> None:
    a, b = bus_pair
    got: list[tuple[str, bytes]] = []
    b.subscribe("opt/x/detections/*", lambda s: got.append((s.key, s.payload)))
    b.subscribe("opt/x/other", lambda s: got.append(("wrong", s.payload)))
    pub = a.publisher("opt/x/detections/k1")
    assert wait_for_subscribers(pub)
    for i in range(200):
        pub.put(str(i).encode())
    wait_for(lambda: len(got) >= 200, what="200 samples")
    assert got == [("opt/x/detections/k1", str(i).encode()) for i in range(200)]


def test_put_without_publisher(bus_pair: tuple) -> None:
    a, b = bus_pair
    got: list[bytes] = []
    b.subscribe("opt/x/**", lambda s: got.append(s.payload))
    assert wait_for_subscribers(a.publisher("opt/x/ground_truth"))
    a.put("opt/x/ground_truth", b"gt")
    wait_for(lambda: got == [b"gt"], what="one sample")


def test_closed_subscription_receives_nothing(bus_pair: tuple) -> None:
    a, b = bus_pair
    got: list[bytes] = []
    sub = b.subscribe("opt/x/t", lambda s: got.append(s.payload))
    pub = a.publisher("opt/x/t")
    assert wait_for_subscribers(pub)
    pub.put(b"1")
    wait_for(lambda: got == [b"1"], what="first sample")
    sub.close()
    sub.close()  # idempotent
    wait_for(lambda: not pub.has_subscribers(), what="unmatch")
    pub.put(b"2")
    time.sleep(0.2)
    assert got == [b"1"]


def test_a_raising_handler_does_not_stop_delivery(bus_pair: tuple) -> None:
    a, b = bus_pair
    if isinstance(b, MemoryBus):
        pytest.skip("MemoryBus runs handlers on the caller's stack by design")
    got: list[bytes] = []

    def handler(sample: object) -> None:
        got.append(sample.payload)  # type: ignore[attr-defined]
        raise RuntimeError("handler bug")

    b.subscribe("opt/x/t", handler)
    pub = a.publisher("opt/x/t")
    assert wait_for_subscribers(pub)
    pub.put(b"1")
    pub.put(b"2")
    wait_for(lambda: got == [b"1", b"2"], what="both samples despite the exception")


def test_liveliness_tokens_appear_and_vanish(bus_pair: tuple) -> None:
    a, b = bus_pair
    events: list[tuple[str, bool]] = []
    b.subscribe_liveliness("opt/x/alive/*", lambda k, alive: events.append((k, alive)))
    token = a.declare_token("opt/x/alive/sim")
    wait_for(lambda: ("opt/x/alive/sim", True) in events, what="token appears")
    assert b.alive("opt/x/alive/*") == ["opt/x/alive/sim"]
    token.close()
    wait_for(lambda: ("opt/x/alive/sim", False) in events, what="token vanishes")
    assert b.alive("opt/x/alive/*") == []


def test_tokens_of_a_closed_session_vanish(bus_pair: tuple) -> None:
    a, b = bus_pair
    token = a.declare_token("opt/x/alive/tracker")  # keep it: Zenoh undeclares on drop
    wait_for(lambda: b.alive("opt/x/alive/*") == ["opt/x/alive/tracker"], what="token")
    a.close()
    del token
    wait_for(lambda: b.alive("opt/x/alive/*") == [], what="token gone with its session")


def test_queries_reach_queryables(bus_pair: tuple) -> None:
    a, b = bus_pair
    b.serve("opt/x/calibration/k1", lambda key, payload: b"pose:" + (payload or b"none"))
    b.serve("opt/x/calibration/k2", lambda key, payload: None)  # declines to answer
    time.sleep(0.2)
    replies = a.query("opt/x/calibration/k1", b"please")
    assert [(r.key, r.payload) for r in replies] == [("opt/x/calibration/k1", b"pose:please")]
    assert a.query("opt/x/calibration/k2") == []
    assert a.query("opt/x/nothing/here", timeout_s=0.3) == []


def test_memory_bus_refuses_put_after_close() -> None:
    bus = MemoryBus()
    bus.close()
    with pytest.raises(RuntimeError, match="closed"):
        bus.put("opt/x/t", b"")
