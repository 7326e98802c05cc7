"""The clients in ``examples/`` against a live output node (and a few offline checks).

One live network (simulator, tracker, output node with a UDP sink, an OSC sink and the
WebSocket stream) serves every test of this module: the example programs run as
processes against it, the parsing modules of the TouchDesigner and p5.js examples run
on what it sent (the p5.js one under ``node``), and the OSC stream is parsed with
python-osc.
"""

from __future__ import annotations

import importlib.util
import json
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from pythonosc.osc_bundle import OscBundle
from pythonosc.osc_message import OscMessage
from pythonosc.parsing import osc_types
from websockets.sync.client import connect

from tests.conftest import ROOT, python_env
from tests.opt_live import LiveNetwork, free_udp_port, is_heartbeat, run_node

pytestmark = [pytest.mark.zenoh, pytest.mark.slow]

EXAMPLES = ROOT / "examples"
FRAMES_WANTED = 30
WS_MESSAGES = 40


def _load(path: Path) -> Any:
    spec = importlib.util.spec_from_file_location(path.stem, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@dataclass
class Live:
    net: LiveNetwork
    receiver_port: int
    ws_messages: list[str]


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Live]:
    receiver_port = free_udp_port()
    net = LiveNetwork(
        tmp_path_factory.mktemp("examples"),
        {"td": {"format": "opt-v2"}},
        extra_udp=[{"host": "127.0.0.1", "port": receiver_port, "format": "opt-v2"}],
        osc=True,
        web=True,
    )
    with net:
        net.wait_for_frames("td", FRAMES_WANTED)
        messages = []
        with connect(f"ws://127.0.0.1:{net.web_port}/ws", open_timeout=10) as ws:
            while len(messages) < WS_MESSAGES:
                messages.append(ws.recv(timeout=10))
        yield Live(net, receiver_port, messages)


def _run(*args: str, timeout_s: float = 40.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, *args],
        capture_output=True,
        text=True,
        timeout=timeout_s,
        env=python_env(),
        cwd=ROOT,
    )


# ----------------------------------------------------------------------------- python


def test_udp_receiver_prints_five_live_frames_as_json(live: Live) -> None:
    result = _run(
        str(EXAMPLES / "python" / "udp_receiver.py"), "--host", "127.0.0.1",
        "--port", str(live.receiver_port), "--count", "5", "--json", "--timeout", "20",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    records = [json.loads(line) for line in result.stdout.splitlines()]
    frames = [r for r in records if r["kind"] == "tracks"]
    assert len(frames) == 5
    assert all(r["kind"] == "heartbeat" and isinstance(r["alive_ids"], list) for r in records
               if r["kind"] != "tracks")  # fmt: skip
    seqs = [f["seq"] for f in frames]
    assert seqs == list(range(seqs[0], seqs[0] + 5))
    for frame in frames:
        assert frame["format"] == "opt-v2" and frame["frame_id"] == "world"
        assert abs(frame["stamp"] - time.time()) < 60
        assert frame["tracks"]  # the crowd is in the room by now
        for track in frame["tracks"]:
            assert isinstance(track["id"], int)
            assert all(isinstance(track[k], float) for k in ("x", "y", "height", "age"))


def test_udp_receiver_text_mode_and_bad_input(tmp_path: Path) -> None:
    port = free_udp_port()
    proc = subprocess.Popen(
        [sys.executable, str(EXAMPLES / "python" / "udp_receiver.py"), "--host", "127.0.0.1",
         "--port", str(port), "--count", "3", "--timeout", "20"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=python_env(), cwd=ROOT,
    )  # fmt: skip
    assert proc.stderr is not None
    assert "listening" in proc.stderr.readline()
    v1_with_nan = (
        b'{"header":{"seq":7,"stamp":{"sec":1441244414,"nsec":266356327},"frame_id":"world"},'
        b'"tracks":[{"id":170,"x":0.740519,"y":-3.21577,"height":nan,"age":79.4518,'
        b'"confidence":-0}]}' + b"\0" * 100  # OpenPTrack v1's NaN, old zero padding
    )
    spaced = json.dumps(  # optsimulate.py / justsim.py style: spaces, no NUL
        {"header": {"stamp": {"sec": 1, "nsec": 2}, "frame_id": "world", "seq": 8},
         "people_tracks": [{"confidence": 0.6, "age": 54.0, "height": 1.19, "y": 1.5,
                            "x": 0.38, "id": 59}]}
    ).encode()  # fmt: skip
    heartbeat = b'{"header":{"seq":5694,"stamp":{"sec":1,"nsec":0},"frame_id":"heartbeat"},'
    heartbeat += b'"alive_IDs":[59,60],"max_ID":60}\0'
    two = b'{"header":{"seq":9},"tracks":[]}{"header":{"seq":10},"tracks":[]}'
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        for data in (b"", b"{", b"\xff\xfe\x00", b"[1,2]", heartbeat, v1_with_nan, spaced, two):
            tx.sendto(data, ("127.0.0.1", port))
            time.sleep(0.01)
    out, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
    assert out.splitlines() == [
        "heartbeat seq=5694 alive=[59, 60] max_id=60",
        "seq=7 tracks=1 | 170 (0.74, -3.22) h=?",
        "seq=8 tracks=1 | 59 (0.38, 1.50) h=1.19",
        "seq=9 tracks=0",
    ]
    assert "unreadable datagram" in err


def test_zenoh_subscriber_prints_five_live_frames_as_json(live: Live) -> None:
    result = _run(
        str(EXAMPLES / "python" / "zenoh_subscriber.py"), "-e", live.net.hub,
        "--site", "default", "--count", "5", "--json",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    frames = [json.loads(line) for line in result.stdout.splitlines()]
    assert len(frames) == 5
    seqs = [f["seq"] for f in frames]
    assert seqs == sorted(seqs) and len(set(seqs)) == 5
    for frame in frames:
        assert frame["frame_id"] == "world" and frame["tracks"]
        assert frame["max_id"] >= max(t["id"] for t in frame["tracks"])
        for track in frame["tracks"]:
            assert set(track) >= {"id", "x", "y", "z", "height", "vx", "vy", "visibility"}


# ------------------------------------------------------------------------ touchdesigner


class _Table:
    def __init__(self) -> None:
        self.rows: list[list] = []

    def clear(self) -> None:
        self.rows = []

    def appendRow(self, row: list) -> None:  # noqa: N802 - TouchDesigner's name
        self.rows.append(list(row))


class _Comp:
    def __init__(self, **ops: _Table) -> None:
        self.ops = ops

    def op(self, name: str) -> _Table | None:
        return self.ops.get(name)


class _Dat:
    def __init__(self, parent: _Comp) -> None:
        self._parent = parent

    def parent(self) -> _Comp:
        return self._parent


def test_touchdesigner_callbacks_fill_the_tables(live: Live) -> None:
    td = _load(EXAMPLES / "touchdesigner" / "udp_in_callbacks.py")
    tracks, alive = _Table(), _Table()
    dat = _Dat(_Comp(tracks=tracks, alive=alive))
    datagrams = live.net.captures["td"].datagrams()
    people = beats = 0
    for data in datagrams:
        parsed = td.parse_message(data)
        document = json.loads(data.rstrip(b"\0"))
        before = [list(r) for r in tracks.rows]
        td.onReceive(dat, 0, data.decode(errors="replace"), data, None)
        if is_heartbeat(data):
            beats += 1
            assert parsed is None and tracks.rows == before  # the table stays
            assert alive.rows == [["id"], *[[i] for i in document["alive_IDs"]]]
            continue
        expected = sorted(document["people_tracks"], key=lambda t: t["id"])
        assert [t["id"] for t in parsed] == [t["id"] for t in expected]
        assert tracks.rows[0] == ["id", "x", "y", "height", "age", "confidence"]
        assert len(tracks.rows) == len(expected) + 1
        for row, t in zip(tracks.rows[1:], expected, strict=True):
            assert row[0] == t["id"] and row[1] == pytest.approx(t["x"], abs=1e-4)
        people += bool(parsed)
    assert people >= FRAMES_WANTED and beats > 0
    for bad in (b"", b"{", b"\x00", b"[]", b'{"header":{}}', b'{"tracks":[{"x":1}]}'):
        assert td.parse_message(bad) in (None, [])
        td.onReceive(dat, 0, "", bad, None)  # never raises


# --------------------------------------------------------------------------------- p5.js

P5_RUNNER = r"""
const S = require(process.argv[1]);
const lines = require("fs").readFileSync(0, "utf8").split("\n").filter(Boolean);
let state = S.createState(5);
const seqs = [];
for (const line of lines) {
  state = S.applyMessage(state, JSON.parse(line));
  seqs.push(state.seq);
}
console.log(JSON.stringify({
  state, seqs,
  urls: [
    S.streamUrl({ hostname: "", search: "" }),
    S.streamUrl({ hostname: "stage.local", search: "" }),
    S.streamUrl({ hostname: "x", search: "?a=1&ws=ws%3A%2F%2F10.0.0.5%3A9000%2Fws" }),
  ],
}));
"""


def test_p5_stream_module_turns_live_messages_into_state(live: Live) -> None:
    if shutil.which("node") is None:
        pytest.skip("node is not installed")
    messages = [*live.ws_messages, "not json", '{"type":"other"}', "null"]
    out = run_node(
        P5_RUNNER.replace("process.argv[1]", json.dumps(str(EXAMPLES / "p5js" / "opt_stream.js"))),
        "".join(json.dumps(m) + "\n" for m in messages),
    )
    result = json.loads(out)
    state = result["state"]
    docs = [json.loads(m) for m in live.ws_messages]
    assert docs[0]["type"] == "scene"
    frames = [d for d in docs if d["type"] == "tracks"]
    assert state["room"] == [0, 0, 10, 10] and state["site"] == "default"
    assert state["frames"] == len(frames) == WS_MESSAGES - 1
    assert state["errors"] == 3
    last = frames[-1]
    assert state["seq"] == last["seq"] and state["maxId"] == last["max_id"]
    assert [t["id"] for t in state["tracks"]] == sorted(t["id"] for t in last["tracks"])
    assert state["aliveIds"] == last["alive_ids"]
    for track in state["tracks"]:
        trail = state["trails"][str(track["id"])]
        assert 1 <= len(trail) <= 5 and trail[-1] == [track["x"], track["y"]]
    assert set(state["trails"]) == {str(t["id"]) for t in state["tracks"]}
    assert result["urls"] == [
        "ws://localhost:8080/ws",
        "ws://stage.local:8080/ws",
        "ws://10.0.0.5:9000/ws",
    ]


def test_p5_sketch_files_are_valid_javascript() -> None:
    if shutil.which("node") is None:
        pytest.skip("node is not installed")
    for name in ("sketch.js", "opt_stream.js"):
        check = subprocess.run(
            ["node", "--check", str(EXAMPLES / "p5js" / name)], capture_output=True, text=True
        )
        assert check.returncode == 0, check.stderr
    html = (EXAMPLES / "p5js" / "index.html").read_text()
    for script in ("p5.min.js", "opt_stream.js", "sketch.js"):
        assert f'src="{script}"' in html
    assert html.index("opt_stream.js") < html.index("sketch.js")


# ----------------------------------------------------------------------------------- OSC


def _type_tags(message: OscMessage) -> str:
    dgram = message.dgram
    _address, index = osc_types.get_string(dgram, 0)
    tags, _ = osc_types.get_string(dgram, index)
    return tags


def test_osc_bundles_have_the_documented_addresses_and_types(live: Live) -> None:
    json_frames = {}
    for data in live.net.captures["td"].datagrams():
        if not is_heartbeat(data):
            doc = json.loads(data.rstrip(b"\0"))
            stamp = doc["header"]["stamp"]
            json_frames[(stamp["sec"], stamp["nsec"])] = doc["people_tracks"]
    bundles = live.net.captures["osc"].datagrams()
    assert len(bundles) >= FRAMES_WANTED
    matched = 0
    for dgram in bundles:
        assert OscBundle.dgram_is_bundle(dgram)
        messages = list(OscBundle(dgram))
        assert all(isinstance(m, OscMessage) for m in messages)
        first, *tracks, last = messages
        assert first.address == "/opt/frame" and _type_tags(first) == ",iiiii"
        seq, sec, nsec, count, max_id = first.params
        assert seq >= 1 and abs(sec - time.time()) < 600 and 0 <= nsec < 10**9
        assert count == len(tracks)
        for m in tracks:
            assert m.address == "/opt/track" and _type_tags(m) == ",ifffff"
            assert 1 <= m.params[0] <= max_id
        assert last.address == "/opt/alive"
        assert _type_tags(last) == "," + "i" * len(last.params)
        assert all(1 <= i <= max_id for i in last.params)
        assert [m.params[0] for m in tracks] == sorted(m.params[0] for m in tracks)
        same = json_frames.get((sec, nsec))
        if same is not None:  # the same frame as the UDP JSON sink sent
            matched += 1
            assert [m.params[0] for m in tracks] == [t["id"] for t in same]
            for m, t in zip(tracks, same, strict=True):
                assert m.params[1] == pytest.approx(t["x"], abs=1e-5)
                assert m.params[2] == pytest.approx(t["y"], abs=1e-5)
    assert matched >= FRAMES_WANTED
    assert sum(len(list(OscBundle(d))) > 2 for d in bundles) >= FRAMES_WANTED  # people


# ----------------------------------------------------------------------------------- Max


def test_max_patch_is_a_valid_patcher_with_the_osc_chain() -> None:
    patcher = json.loads((EXAMPLES / "max" / "opt_osc.maxpat").read_text())["patcher"]
    boxes = {b["box"]["id"]: b["box"] for b in patcher["boxes"]}
    assert len(boxes) == len(patcher["boxes"])
    by_text = {b.get("text"): i for i, b in boxes.items() if b["maxclass"] == "newobj"}
    receive = by_text["udpreceive 7000"]
    route = by_text["route /opt/frame /opt/track /opt/alive"]
    frame = by_text["unpack i i i i i"]
    track = by_text["unpack i f f f f f"]
    assert boxes[route]["numoutlets"] == 4 and boxes[track]["numoutlets"] == 6
    assert boxes[track]["outlettype"] == ["int"] + ["float"] * 5
    links = set()
    for line in patcher["lines"]:
        (src, outlet), (dst, inlet) = line["patchline"]["source"], line["patchline"]["destination"]
        assert outlet < boxes[src]["numoutlets"] and inlet < boxes[dst]["numinlets"]
        links.add((src, outlet, dst))
    assert {(receive, 0, route), (route, 0, frame), (route, 1, track)} <= links
    assert any(dst.startswith("obj") and src == route and o == 2 for src, o, dst in links)
    comments = [b["text"] for b in boxes.values() if b["maxclass"] == "comment"]
    assert any("/opt/track: id x y height age confidence" in c for c in comments)
    for box in boxes.values():
        assert len(box["patching_rect"]) == 4


# ------------------------------------------------------------------------------ READMEs


@pytest.mark.parametrize("folder", ["python", "touchdesigner", "max", "processing", "p5js"])
def test_each_example_has_a_readme_with_the_output_settings(folder: str) -> None:
    text = (EXAMPLES / folder / "README.md").read_text()
    for heading in ("## What it is", "## Typical usage", "## Output settings"):
        assert heading in text
    index = (EXAMPLES / "README.md").read_text()
    assert f"]({folder}/" in index
