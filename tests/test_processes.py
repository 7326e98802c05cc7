"""Real processes talking over Zenoh on loopback (free port, multicast scouting off)."""

from __future__ import annotations

import re
import signal
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

import orjson
import pytest

from openptrack_py.config import ZenohConfig
from openptrack_py.messages import decode_detection_batch
from openptrack_py.recordings import read_recording
from openptrack_py.transport.zenoh_bus import ZenohBus
from tests.conftest import free_port, wait_for
from tests.procs.publisher import batch

pytestmark = pytest.mark.zenoh


def _start_recorder(
    spawn: Callable[..., subprocess.Popen[str]], out: Path, listen: str
) -> subprocess.Popen[str]:
    return spawn(
        "-m", "openptrack_py.nodes.record",
        "-l", listen,
        "--set", "zenoh.hub=null",  # no hub: the publisher connects straight to this listener
        "--no-multicast-scouting",
        "-o", str(out),
        "-k", "opt/default/detections/**",
        name="recorder",
    )  # fmt: skip


def _stop(proc: subprocess.Popen[str]) -> str:
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=15) == 0
    return Path(proc.log_path).read_text()  # type: ignore[attr-defined]


def _final_counters(log: str) -> dict[str, int]:
    line = [x for x in log.splitlines() if " stopped " in x][-1]
    return {k: int(v) for k, v in re.findall(r"(\w+)=(\d+)", line)}


def test_thousand_batches_arrive_complete_and_in_order(
    spawn: Callable[..., subprocess.Popen[str]], tmp_path: Path
) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    out = tmp_path / "received.jsonl"
    recorder = _start_recorder(spawn, out, endpoint)
    publisher = spawn("-m", "tests.procs.publisher", "--connect", endpoint, "--count", "1000")
    assert publisher.wait(timeout=60) == 0, Path(publisher.log_path).read_text()  # type: ignore[attr-defined]
    wait_for(lambda: out.exists() and len(out.read_bytes().splitlines()) >= 1000, 30, "1000 lines")
    log = _stop(recorder)
    lines = list(read_recording(out))
    seqs = [orjson.loads(m.payload)["seq"] for m in lines]
    assert seqs == list(range(1000)), "lost or reordered batches"
    assert all(m.key == "opt/default/detections/k1" for m in lines)
    counters = _final_counters(log)
    assert counters["in"] == 1000 and counters["malformed"] == 0 and counters["dropped"] == 0


def test_malformed_bytes_are_counted_dropped_and_survived(
    spawn: Callable[..., subprocess.Popen[str]], tmp_path: Path
) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    out = tmp_path / "received.jsonl"
    recorder = _start_recorder(spawn, out, endpoint)
    # truncated JSON, a string where an int belongs, NaN, a 10 MB array; then 20 good ones
    publisher = spawn(
        "-m", "tests.procs.publisher", "--connect", endpoint, "--count", "20", "--malformed"
    )  # fmt: skip
    assert publisher.wait(timeout=60) == 0
    wait_for(lambda: out.exists() and len(out.read_bytes().splitlines()) >= 20, 30, "20 lines")
    assert recorder.poll() is None, "the recorder died of bad input"
    log = _stop(recorder)
    lines = list(read_recording(out))
    assert [orjson.loads(m.payload)["seq"] for m in lines] == list(range(20))
    for m in lines:  # only valid messages were written: the strict decoder takes them
        decode_detection_batch(m.payload)
    counters = _final_counters(log)
    assert counters["malformed"] == 4 and counters["in"] == 20
    # rate-limited logging: one warning line for the burst, naming the first problem
    warnings = [x for x in log.splitlines() if "dropped malformed message" in x]
    assert len(warnings) == 1, warnings
    assert "error=" in warnings[0] and "opt/default/detections/k1" in warnings[0]


@pytest.mark.parametrize("stop_signal", [signal.SIGINT, signal.SIGTERM], ids=["sigint", "sigterm"])
def test_record_and_echo_end_cleanly_on_a_signal(
    spawn: Callable[..., subprocess.Popen[str]], tmp_path: Path, stop_signal: signal.Signals
) -> None:
    """Ctrl-C (or SIGTERM) ends ``openptrack record`` and ``echo`` with status 0 and
    keeps what they received: the signal only asks their loop to end, so it can never
    interrupt them inside a lock (their handlers store the signal, nothing more)."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    out = tmp_path / "recorded.jsonl"
    zenoh = ("--set", "zenoh.hub=null", "--no-multicast-scouting")
    record = spawn("-m", "openptrack_py.cli", "record", "-l", endpoint, *zenoh, "-o", str(out),
                   "-k", "detections/**", name="record")  # fmt: skip
    echo = spawn("-m", "openptrack_py.cli", "echo", "opt/default/detections/**", "-e", endpoint,
                 *zenoh, name="echo")  # fmt: skip
    echoed = Path(echo.log_path)  # type: ignore[attr-defined]

    def both_received() -> bool:
        recorded = out.exists() and len(out.read_bytes().splitlines()) >= 1
        return recorded and echoed.read_text().count('"key"') >= 1

    cfg = ZenohConfig(hub=None, connect=[endpoint], listen=[], multicast_scouting=False)
    with ZenohBus(cfg) as bus:  # publish until both have subscribed and received
        pub = bus.publisher("opt/default/detections/k1")
        deadline, seq = time.monotonic() + 60, 0
        while not both_received() and time.monotonic() < deadline:
            pub.put(batch(seq))
            seq += 1
            time.sleep(0.02)
    assert both_received(), "record or echo never received a message"
    for proc in (record, echo):
        proc.send_signal(stop_signal)
    assert record.wait(timeout=15) == 0, Path(record.log_path).read_text()  # type: ignore[attr-defined]
    assert echo.wait(timeout=15) == 0, echoed.read_text()
    said = re.findall(r"recorded (\d+) messages", Path(record.log_path).read_text())  # type: ignore[attr-defined]
    assert said and int(said[-1]) == len(list(read_recording(out))) >= 1
    assert "Traceback" not in echoed.read_text()


@pytest.mark.parametrize("stop_signal", [signal.SIGINT, signal.SIGTERM], ids=["sigint", "sigterm"])
def test_record_sensor_ends_cleanly_on_a_signal(
    spawn: Callable[..., subprocess.Popen[str]], tmp_path: Path, stop_signal: signal.Signals
) -> None:
    """Ctrl-C (or SIGTERM) ends ``openptrack record-sensor`` with status 0 after the
    frame being read: the frames it says it wrote are all listed and replay whole."""
    from openptrack_py.detection.sources import FolderSource

    out = tmp_path / "rec"
    proc = spawn("-m", "openptrack_py.cli", "record-sensor", "sim:crowd", str(out),
                 name="record-sensor")  # fmt: skip
    listed = out / "frames.csv"

    def written() -> int:  # frames listed (the header row not counted)
        return len(listed.read_text().splitlines()) - 1 if listed.exists() else 0

    wait_for(lambda: written() >= 3, 120, "three frames")
    proc.send_signal(stop_signal)
    log = Path(proc.log_path)  # type: ignore[attr-defined]
    assert proc.wait(timeout=30) == 0, log.read_text()
    said = re.findall(r"recorded (\d+) frames", log.read_text())
    rows = written()
    assert said and int(said[-1]) == rows >= 3, log.read_text()
    replayed = list(FolderSource(out).frames())
    assert len(replayed) == rows
    assert all(f.depth is not None and f.depth.shape == replayed[0].depth.shape for f in replayed)
