"""Node runtime: inbox, counters, rate-limited logs, bad-input handling, stats, signals."""

from __future__ import annotations

import io
import json
import logging
import os
import signal
import threading

import pytest

from openptrack_py.messages import (
    Detection,
    DetectionBatch,
    decode_detection_batch,
    decode_node_stats,
    encode_detection_batch,
)
from openptrack_py.runtime import Counters, Inbox, Node, RateLimitedLog, configure_logging
from openptrack_py.runtime.stop import StopRequest
from openptrack_py.transport import MemoryBus, MemoryNetwork


class FakeClock:
    def __init__(self, t: float = 1000.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


def _batch(seq: int) -> bytes:
    det = Detection(x=1.0, y=2.0, z=0.9, height=1.7, confidence=0.9, distance=2.0)
    return encode_detection_batch(DetectionBatch("k1", seq, 1.7e9, "world", (det,)))


# ------------------------------------------------------------------------- inbox


def test_inbox_drops_the_oldest_and_counts_it() -> None:
    dropped: list[int] = []
    inbox: Inbox[int] = Inbox(3, on_drop=lambda: dropped.append(1))
    for i in range(5):
        inbox.push(i)
    assert len(inbox) == 3 and len(dropped) == 2
    assert inbox.drain(timeout=0) == [2, 3, 4]
    assert inbox.get(timeout=0.01) is None


def test_inbox_rejects_zero_capacity() -> None:
    with pytest.raises(ValueError, match="maxsize must be >= 1, got 0"):
        Inbox(0)


# ---------------------------------------------------------------------- counters


def test_counters_report_totals_rates_and_timings() -> None:
    clock = FakeClock()
    c = Counters("sim", clock=clock)
    c.inc("out", 30)
    c.inc("late")
    c.add_timing("step", 0.002)
    c.add_timing("step", 0.004)
    clock.t += 2.0
    snap = c.snapshot()
    assert snap.counters == {"in": 0, "out": 30, "dropped": 0, "malformed": 0, "late": 1}
    assert snap.rates_hz["out"] == 15.0 and snap.rates_hz["late"] == 0.5
    assert snap.timings_ms == {"step": 3.0}
    assert snap.uptime_s == 2.0 and snap.node == "sim" and snap.pid == os.getpid()
    clock.t += 1.0
    again = c.snapshot()
    assert again.rates_hz["out"] == 0.0 and again.counters["out"] == 30  # rates are per interval
    assert again.timings_ms == {}


# --------------------------------------------------------------------------- logs


def test_rate_limited_log_suppresses_and_reports_the_count(
    caplog: pytest.LogCaptureFixture,
) -> None:
    clock = FakeClock()
    limited = RateLimitedLog(logging.getLogger("t"), interval_s=5.0, clock=clock)
    with caplog.at_level(logging.WARNING):
        assert limited.warning("bad", "first")
        assert not limited.warning("bad", "second")
        assert not limited.warning("bad", "third")
        assert limited.warning("other", "another topic is independent")
        clock.t += 5.0
        assert limited.warning("bad", "fourth")
    messages = [r.getMessage() for r in caplog.records]
    assert messages == ["first", "another topic is independent", "fourth"]
    assert caplog.records[-1].fields == {"suppressed": 2}  # type: ignore[attr-defined]


def test_json_log_lines_carry_fields(capsys: pytest.CaptureFixture[str]) -> None:
    configure_logging("tracker", "info", "json")
    logging.getLogger("x").info("stepped", extra={"fields": {"tracks": 3}})
    line = json.loads(capsys.readouterr().err.strip().splitlines()[-1])
    assert line["node"] == "tracker" and line["msg"] == "stepped" and line["tracks"] == 3
    configure_logging("tracker", "info", "text")
    logging.getLogger("x").warning("hello", extra={"fields": {"k": "v"}})
    text = capsys.readouterr().err.strip().splitlines()[-1]
    assert text.endswith("WARNING tracker: hello k=v")


# --------------------------------------------------------------------------- node


def test_node_counts_valid_and_malformed_and_keeps_going(
    caplog: pytest.LogCaptureFixture,
) -> None:
    net = MemoryNetwork()
    sender = MemoryBus(net)
    with MemoryBus(net) as bus, Node("rx", bus, stats_interval_s=0) as node:
        inbox = node.subscribe("opt/default/detections/*", decode_detection_batch)
        key = "opt/default/detections/k1"
        with caplog.at_level(logging.WARNING):
            sender.put(key, _batch(0))
            for bad in (b"", b"{", b'{"v":1}', b"\xff" * 10, _batch(1).replace(b"0.9", b"9.9")):
                sender.put(key, bad)
            sender.put(key, _batch(2))
        got = [r.message.seq for r in inbox.drain(timeout=0)]
        assert got == [0, 2]
        assert node.counters.get("in") == 2 and node.counters.get("malformed") == 5
        warnings = [r for r in caplog.records if "malformed" in r.getMessage()]
        assert len(warnings) == 1  # rate-limited
        assert warnings[0].fields["key"] == key  # type: ignore[attr-defined]


def test_node_drops_oldest_when_its_loop_falls_behind() -> None:
    net = MemoryNetwork()
    sender = MemoryBus(net)
    with MemoryBus(net) as bus, Node("rx", bus, stats_interval_s=0) as node:
        inbox = node.subscribe("opt/default/detections/*", decode_detection_batch, maxsize=4)
        for seq in range(10):
            sender.put("opt/default/detections/k1", _batch(seq))
        assert [r.message.seq for r in inbox.drain(timeout=0)] == [6, 7, 8, 9]
        assert node.counters.get("dropped") == 6 and node.counters.get("in") == 10


def test_node_announces_liveliness_and_publishes_stats() -> None:
    net = MemoryNetwork()
    watcher = MemoryBus(net)
    stats: list[bytes] = []
    watcher.subscribe("opt/lab/stats/*", lambda s: stats.append(s.payload))
    bus = MemoryBus(net)
    node = Node("sim", bus, site="lab", stats_interval_s=3600)
    node.start()
    assert watcher.alive("opt/lab/alive/*") == ["opt/lab/alive/sim"]
    pub = node.publisher("opt/lab/detections/k1")
    pub.put(_batch(0))
    node.publish_stats()
    snap = decode_node_stats(stats[-1])
    assert snap.node == "sim" and snap.counters["out"] == 1
    node.close()
    assert watcher.alive("opt/lab/alive/*") == []
    assert not node.running
    # a final snapshot goes out on close
    assert decode_node_stats(stats[-1]).counters["out"] == 1


def test_sigterm_stops_the_node_cleanly() -> None:
    with MemoryBus() as bus, Node("sig", bus, stats_interval_s=0) as node:
        previous = signal.getsignal(signal.SIGTERM)
        try:
            node.install_signal_handlers()
            os.kill(os.getpid(), signal.SIGTERM)
            assert node.wait(timeout=5.0)
            assert not node.running
        finally:
            signal.signal(signal.SIGTERM, previous)
            signal.signal(signal.SIGINT, signal.default_int_handler)


def test_a_signal_arriving_while_its_thread_holds_the_stop_lock_does_not_hang_it() -> None:
    # Python runs a handler between two bytecodes of the main thread, possibly just after
    # Event.wait took the event's lock again; a handler calling Event.set() then waits
    # for its own thread forever (the likely cause of a launcher that once did not stop on
    # SIGTERM). Here the handler runs with that lock held by its own thread, as it would
    # in that window.
    announced: list[str] = []
    stop = StopRequest(on_signal=announced.append)
    handled = threading.Event()

    def handler_inside_the_window() -> None:
        with stop._event._cond:  # the lock Event.wait holds between wake-up and return
            stop.from_signal(signal.SIGTERM)
        handled.set()

    thread = threading.Thread(target=handler_inside_the_window, daemon=True)
    thread.start()
    thread.join(timeout=10.0)
    assert handled.is_set(), "the signal handler blocked on a lock its own thread holds"
    assert stop.wait(timeout=5.0) and stop.is_set()
    assert announced == ["SIGTERM"]  # announced once, outside the handler
    assert stop.wait(0) and announced == ["SIGTERM"]


def test_a_stop_request_waits_out_its_timeout_when_nobody_asks() -> None:
    stop = StopRequest()
    assert not stop.wait(0.05) and not stop.is_set()
    stop.set()
    assert stop.wait(None)


def test_stats_go_out_periodically_on_their_own_thread() -> None:
    net = MemoryNetwork()
    watcher = MemoryBus(net)
    got: list[bytes] = []
    watcher.subscribe("opt/default/stats/n", lambda s: got.append(s.payload))
    with MemoryBus(net) as bus, Node("n", bus, stats_interval_s=0.05):
        from tests.conftest import wait_for

        wait_for(lambda: len(got) >= 3, 10, "three periodic stats")
    assert all(decode_node_stats(p).node == "n" for p in got)


def test_text_formatter_includes_exceptions() -> None:
    stream = io.StringIO()
    configure_logging("n", "info", "text")
    handler = logging.getLogger().handlers[0]
    handler.setStream(stream)  # type: ignore[attr-defined]
    try:
        raise RuntimeError("boom")
    except RuntimeError:
        logging.getLogger("x").exception("failed")
    assert "RuntimeError: boom" in stream.getvalue()


@pytest.mark.parametrize("flag", ["-e", "-l"])
def test_a_bad_endpoint_flag_is_a_config_error_naming_it(flag: str) -> None:
    import argparse

    from openptrack_py.config import ZenohConfig
    from openptrack_py.errors import ConfigError
    from openptrack_py.runtime.args import add_zenoh_arguments, zenoh_from_args

    parser = argparse.ArgumentParser()
    add_zenoh_arguments(parser)
    args = parser.parse_args([flag, "tcp/127.0.0.1:"])
    with pytest.raises(ConfigError, match=r"(?s)zenoh flags \(-e, -l\).*port must be a number"):
        zenoh_from_args(ZenohConfig(), args)


def test_a_node_stopped_while_it_joins_the_network_stops_cleanly(
    monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    """Ctrl-C (or a launcher's stop) before the node's own handlers are installed, while
    its session settles on a slow machine: a clean stop, exit 0, no traceback."""
    from openptrack_py.runtime import entry

    def interrupted(*_args: object, **_kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(entry, "bus_from_args", interrupted)
    parser = entry.node_parser("openptrack node sim", "a node")
    body_ran = []
    code = entry.run_node("sim", parser, lambda *a: body_ran.append(a), [])
    assert code == entry.EXIT_OK and not body_ran
    out, err = capfd.readouterr()
    assert "INFO sim: stopped" in out + err and "Traceback" not in out + err
