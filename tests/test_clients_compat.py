"""OpenPTrack's own clients against a live output node, one sink configuration at a time.

A real simulator, tracker and output node run (``openptrack launch``); the output node has
one UDP sink per configuration below, each aimed at a socket of this test. Every client's
parsing rule is re-implemented here from OpenPTrack's clients (as docs/clients.md describes
them) and applied to the captured datagrams:

* with the settings ``docs/clients.md`` documents for that client, every datagram of every
  matching sink must parse the way the client needs;
* the breaking cases the documentation names must really break, so the table is evidence.

It also checks the wire format itself on every datagram: one compact JSON object, header
first and the tracks array last, integer id/seq/sec/nsec, never NaN, the trailing NUL
exactly as configured, datagram size limits, heartbeats also while the room is empty.
"""

from __future__ import annotations

import itertools
import json
import re
import shutil
import socket
import struct
import subprocess
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from openptrack_py.config import UdpSinkConfig
from openptrack_py.messages import Track
from openptrack_py.output.opt_json import encode_tracks
from tests.conftest import ROOT
from tests.opt_live import (
    LiveNetwork,
    free_udp_port,
    has_tracks,
    is_heartbeat,
    multicast_works,
    run_node,
)

pytestmark = [pytest.mark.zenoh, pytest.mark.slow]

SINKS: dict[str, dict[str, Any]] = {
    "v2": {"format": "opt-v2"},
    "v2_nonul": {"format": "opt-v2", "trailing_nul": False},
    "v2_8k": {"format": "opt-v2", "max_datagram_bytes": 8192},
    "v1": {"format": "opt-v1"},
    "v1_legacy": {"format": "opt-v1", "heartbeat": False, "max_datagram_bytes": 2048},
    "v1_nonul": {"format": "opt-v1", "trailing_nul": False, "heartbeat": False},
    "v1_split": {"format": "opt-v1", "heartbeat": False, "max_datagram_bytes": 512},
}
SETTINGS = {name: UdpSinkConfig(**fields) for name, fields in SINKS.items()}
ROOT_KEY = {"opt-v2": "people_tracks", "opt-v1": "tracks"}
TRACK_KEYS = ["id", "x", "y", "height", "age", "confidence"]
MULTICAST_GROUP = "224.0.0.1"
MULTICAST_COUNT = 20
FRAMES_WANTED = 60  # frames with people on every sink (2 s at 30 Hz)


# ------------------------------------------------------------------ the live network


@dataclass
class Captured:
    """What the live run produced."""

    timed: dict[str, list[tuple[float, bytes]]]
    multicast: list[dict[str, Any]] | None  # node dgram receiver's results, if multicast works
    log: str

    def datagrams(self, name: str) -> list[bytes]:
        return [d for _, d in self.timed[name]]


NODE_MULTICAST = r"""
const dgram = require("dgram");
const [port, group, count] = [Number(process.argv[1]), process.argv[2], Number(process.argv[3])];
const sock = dgram.createSocket({ type: "udp4", reuseAddr: true });
let n = 0;
const timer = setTimeout(() => process.exit(3), 45000);
// node-ptrack.js uses once('message'); on('message') checks many datagrams with its rule
sock.on("message", (msg) => {
  const s = msg.toString();
  const out = s.substr(0, s.indexOf("]}") + 2);
  let keys = null, error = null, people = 0;
  try {
    const doc = JSON.parse(out);
    keys = Object.keys(doc);
    people = doc.tracks.length;
  } catch (e) { error = String(e); }
  console.log(JSON.stringify({ bytes: msg.length, out, keys, error }));
  if (people > 0) n += 1;  // count frames with people; print every datagram
  if (n >= count) { clearTimeout(timer); sock.close(); }
});
sock.bind(port, () => {
  sock.addMembership(group);
  console.log(JSON.stringify({ ready: true }));
});
"""


@pytest.fixture(scope="module")
def captured(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Captured]:
    workdir = tmp_path_factory.mktemp("compat")
    extra: list[dict[str, Any]] = []
    listener = None
    if shutil.which("node") and multicast_works(MULTICAST_GROUP):
        port = free_udp_port()
        extra.append(
            {"host": MULTICAST_GROUP, "port": port, "mode": "multicast", "format": "opt-v1",
             "heartbeat": False}
        )  # fmt: skip
        listener = subprocess.Popen(
            ["node", "-e", NODE_MULTICAST, str(port), MULTICAST_GROUP, str(MULTICAST_COUNT)],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        )  # fmt: skip
        assert listener.stdout is not None
        ready = listener.stdout.readline()
        assert ready.strip() == '{"ready":true}', ready + listener.stdout.read()
    net = LiveNetwork(workdir, SINKS, extra_udp=extra)
    try:
        with net:
            for name in SINKS:
                net.wait_for_frames(name, FRAMES_WANTED)
            time.sleep(0.3)  # a heartbeat or two after the last counted frame
        multicast = None
        if listener is not None:
            out, _ = listener.communicate(timeout=30)
            assert listener.returncode == 0, out
            multicast = [json.loads(line) for line in out.splitlines()]
        yield Captured({n: net.captures[n].timed() for n in SINKS}, multicast, net.log())
    finally:
        if listener is not None and listener.poll() is None:
            listener.kill()
            listener.wait()


# ----------------------------------------------------------- docs/clients.md settings


def _documented() -> dict[str, dict[str, str]]:
    """The settings table of docs/clients.md: client cell -> column -> cell text."""
    text = (ROOT / "docs" / "clients.md").read_text(encoding="utf-8")
    section = text.split("## UDP JSON: settings per OpenPTrack client", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("|")]
    header = [c.strip() for c in rows[0].strip("|").split("|")]
    table = {}
    for line in rows[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        table[cells[0]] = dict(zip(header, cells, strict=True))
    return table


def _matches(cell: str, value: object) -> bool:
    """Whether a sink setting satisfies a documented cell ("either", "`false`", "≤ 2048")."""
    cell = cell.replace("`", "").strip()
    if cell == "either":
        return True
    if isinstance(value, bool):
        return cell == str(value).lower()
    if isinstance(value, int):
        limit = int(re.search(r"\d+", cell).group())  # type: ignore[union-attr]
        return value <= limit if cell.startswith("≤") else value == limit
    return cell == value


def sinks_for(client: str) -> list[str]:
    """The captured sinks whose settings match what docs/clients.md says ``client`` needs."""
    row = next(v for k, v in _documented().items() if client in k)
    columns = ("format", "trailing_nul", "heartbeat", "max_datagram_bytes")
    return [
        name
        for name, cfg in SETTINGS.items()
        if all(_matches(row[c], getattr(cfg, c)) for c in columns)
    ]


# ---------------------------------------------------- the clients' rules, re-implemented


def strict_json(text: str) -> Any:
    """One JSON document, nothing after it, no NaN/Infinity (rapidjson, JSON.parse)."""

    def reject(token: str) -> None:
        raise ValueError(f"non-finite number {token}")

    return json.loads(text, parse_constant=reject)


def optreceiver(datagram: bytes) -> dict:
    """``optreceiver.py``: ``recvfrom(8192)``, ``data.rstrip("\\0")``, ``json.loads``."""
    return json.loads(datagram[:8192].rstrip(b"\0"))


def td_udp_example(datagram: bytes) -> list:
    """TouchDesigner ``udp_example.py``: ``recvfrom(2048)``, slice, ``['tracks']``."""
    msg = datagram[:2048].decode("utf-8")
    start = msg.find('{"header')
    end = msg.find("]}") + 2
    return json.loads(msg[start:end])["tracks"]  # JSONDecodeError / KeyError: uncaught


def processing_p5_opt_udp(datagram: bytes) -> list[tuple[float, float, float]]:
    """Processing ``p5_opt_udp.pde``: drop exactly one byte, parse, ``tracks``.

    ``JSONObject.parse`` reads one object and ignores what follows it (``raw_decode``);
    ``getJSONArray("tracks")`` is outside the sketch's ``try``.
    """
    text = datagram[: len(datagram) - 1].decode("utf-8")  # subset(data, 0, len - 1)
    obj, _ = json.JSONDecoder().raw_decode(text)
    return [(float(t["id"]), float(t["x"]), float(t["y"])) for t in obj["tracks"]]


def max_parse_opt(datagram: bytes) -> list[list] | None:
    """Max ``net.udp.recvzeropad`` + ``parseOPT.js``; ``None`` when it does not act.

    recvzeropad strips ``\\u0000.*``; the datagram becomes a Max message (atoms split at
    spaces), which parseOPT.js joins back without spaces before ``JSON.parse``.
    """
    text = re.sub("\x00.*", "", datagram.decode("utf-8"))
    obj = strict_json("".join(text.split(" ")))
    if "tracks" not in obj:
        return None
    h = obj["header"]
    return [
        [t["id"], t["x"], t["y"], t["height"], t["age"], t["confidence"],
         h["stamp"]["sec"], h["stamp"]["nsec"], h["seq"]]
        for t in obj["tracks"]
    ]  # fmt: skip


def json_socket_reader(datagram: bytes) -> dict:
    """TouchDesigner ``JsonSocketReader``: up to the first NUL, NaN patch, one document."""
    text = datagram[:65507].split(b"\0", 1)[0].decode("utf-8")
    return strict_json(text.replace("NaN", '"Null"'))


def _get_int(value: Any) -> int:  # rapidjson GetInt: asserts a 32-bit integer
    if type(value) is not int or not -(2**31) <= value < 2**31:
        raise TypeError(f"GetInt on {value!r}")
    return value


def _get_float(track: dict, key: str) -> float:  # GetFloat, -1 when missing
    if key not in track:
        return -1.0
    value = track[key]
    if type(value) not in (int, float):
        raise TypeError(f"GetFloat on {value!r}")
    return struct.unpack("f", struct.pack("f", value))[0]


class OptChop:
    """TouchDesigner ``OPT_CHOP``: documents per cook -> one row per person."""

    def __init__(self) -> None:
        self.rows: dict[int, dict[str, float]] = {}
        self.alive: list[int] = []
        self.max_id: int | None = None
        self.warnings: list[str] = []

    def cook(self, documents: list[dict]) -> None:
        latest: dict[str, dict] = {}
        for doc in documents:  # within one cook the highest seq per frame_id wins
            seq = _get_int(doc["header"]["seq"])
            frame_id = doc["header"]["frame_id"]
            if frame_id not in latest or seq > latest[frame_id]["header"]["seq"]:
                latest[frame_id] = doc
        if "heartbeat" in latest:
            beat = latest["heartbeat"]
            self.max_id = _get_int(beat["max_ID"])
            self.alive = [_get_int(i) for i in beat["alive_IDs"]]
        if "world" in latest:
            doc = latest["world"]
            if "people_tracks" not in doc:
                self.warnings.append("no people_tracks field")
                return
            current = {}
            for t in doc["people_tracks"]:
                row = {k: _get_float(t, k) for k in ("x", "y", "height", "age", "confidence")}
                current[_get_int(t["id"])] = row
            kept = {i: r for i, r in self.rows.items() if i in self.alive and i not in current}
            self.rows = {**kept, **current}  # alive ids missing from the frame keep their row

    def is_alive(self, ident: int) -> bool:
        return ident in self.alive


NODE_PTRACK_BATCH = r"""
const lines = require("fs").readFileSync(0, "utf8").split("\n").filter(Boolean);
for (const hex of lines) {
  const s = Buffer.from(hex, "hex").toString();   // node-ptrack.js: msg -> string
  const out = s.substr(0, s.indexOf("]}") + 2);   // ... and its slice
  let keys = null, error = null;
  try { keys = Object.keys(JSON.parse(out)); } catch (e) { error = String(e); }
  console.log(JSON.stringify({ out, keys, error }));
}
"""


def node_ptrack(datagrams: list[bytes]) -> list[dict[str, Any]]:
    """node-ptrack.js's slice, run in real ``node``, then ``JSON.parse`` of the result."""
    if shutil.which("node") is None:
        pytest.skip("node is not installed")
    out = run_node(NODE_PTRACK_BATCH, "".join(d.hex() + "\n" for d in datagrams))
    return [json.loads(line) for line in out.splitlines()]


def cooks(timed: list[tuple[float, bytes]], period_s: float = 1 / 60) -> list[list[bytes]]:
    """Datagrams grouped by the 60 Hz cook in which they arrived."""
    groups: dict[int, list[bytes]] = defaultdict(list)
    for arrival, data in timed:
        groups[int(arrival / period_s)].append(data)
    return [groups[k] for k in sorted(groups)]


def _text(name: str, data: bytes) -> str:
    return (data[:-1] if SETTINGS[name].trailing_nul else data).decode("utf-8")


def _frames(captured: Captured, name: str) -> list[dict]:
    return [strict_json(_text(name, d)) for d in captured.datagrams(name) if not is_heartbeat(d)]


# ---------------------------------------------------------------------- documentation


def test_every_documented_client_has_matching_live_sinks() -> None:
    documented = _documented()
    assert len(documented) == 7
    for client in documented:
        assert sinks_for(client), f"no captured sink matches the documented row {client!r}"
    assert sinks_for("udp_example.py") == ["v1_legacy", "v1_split"]
    assert sinks_for("OPT_CHOP") == ["v2", "v2_nonul"]
    assert sinks_for("p5_opt_udp.pde") == ["v1_legacy", "v1_split"]


# ---------------------------------------------------------------------- the wire format


def _reject(token: str) -> None:
    raise AssertionError(f"non-finite number {token}")


def _ordered(pairs: list[tuple[str, Any]]) -> dict:
    obj = dict(pairs)
    obj["__keys__"] = [k for k, _ in pairs]
    return obj


@pytest.mark.parametrize("name", list(SINKS))
def test_every_datagram_is_one_compact_json_object_in_openptrack_order(
    captured: Captured, name: str
) -> None:
    cfg = SETTINGS[name]
    now = time.time()
    frames = heartbeats = 0
    for data in captured.datagrams(name):
        assert len(data) <= cfg.max_datagram_bytes
        if cfg.trailing_nul:
            assert data.endswith(b"\0") and not data.endswith(b"\0\0")
            data = data[:-1]
        assert b"\0" not in data
        assert b" " not in data and b"\n" not in data  # compact
        text = data.decode("utf-8")
        # json.loads refuses a second object ("Extra data"), parse_constant NaN/Infinity
        obj = json.loads(text, object_pairs_hook=_ordered, parse_constant=_reject)
        header = obj["header"]
        assert header["__keys__"] == ["seq", "stamp", "frame_id"]
        assert header["stamp"]["__keys__"] == ["sec", "nsec"]
        sec, nsec = header["stamp"]["sec"], header["stamp"]["nsec"]
        assert type(header["seq"]) is int and header["seq"] >= 1
        assert type(sec) is int and abs(sec - now) < 600
        assert type(nsec) is int and 0 <= nsec < 1_000_000_000
        if is_heartbeat(data):
            heartbeats += 1
            assert obj["__keys__"] == ["header", "alive_IDs", "max_ID"]
            assert header["frame_id"] == "heartbeat"
            assert all(type(i) is int and 1 <= i <= obj["max_ID"] for i in obj["alive_IDs"])
            assert type(obj["max_ID"]) is int
            continue
        frames += 1
        assert obj["__keys__"] == ["header", ROOT_KEY[cfg.format]]
        assert header["frame_id"] == "world"
        assert text.find("]}") == len(text) - 2  # the first "]}" closes the last array
        for track in obj[ROOT_KEY[cfg.format]]:
            assert track["__keys__"] == TRACK_KEYS
            assert type(track["id"]) is int and track["id"] >= 1
            for key in TRACK_KEYS[1:]:
                assert type(track[key]) in (int, float)  # %g writes 2.0 as 2, like OpenPTrack
    assert frames >= FRAMES_WANTED
    assert (heartbeats > 0) == cfg.heartbeat


@pytest.mark.parametrize("name", [n for n, c in SETTINGS.items() if c.heartbeat])
def test_heartbeats_come_every_quarter_second_even_in_an_empty_room(
    captured: Captured, name: str
) -> None:
    timed = captured.timed[name]
    beats = [(t, json_socket_reader(d)) for t, d in timed if is_heartbeat(d)]
    first_person = next(t for t, d in timed if has_tracks(d))
    assert any(t < first_person and not b["alive_IDs"] for t, b in beats)  # empty room
    assert any(t > first_person and b["alive_IDs"] for t, b in beats)
    gaps = sorted(b[0] - a[0] for a, b in itertools.pairwise(beats))
    assert 0.2 < gaps[len(gaps) // 2] < 0.35  # median; heartbeat_interval_s = 0.25
    seqs = [b["header"]["seq"] for _, b in beats]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # its own counter
    highest_seen = 0  # max_ID covers every id sent before it on the same socket
    for data in captured.datagrams(name):
        doc = json_socket_reader(data)
        if is_heartbeat(data):
            assert doc["max_ID"] >= highest_seen
        else:
            ids = [t["id"] for t in doc[ROOT_KEY[SETTINGS[name].format]]]
            highest_seen = max([highest_seen, *ids])


def test_formats_and_nul_change_only_what_they_say(captured: Captured) -> None:
    def by_stamp(name: str) -> dict[str, str]:
        out = {}
        for data in captured.datagrams(name):
            if not is_heartbeat(data):
                text = _text(name, data).replace('"people_tracks":', '"tracks":')
                out[text[text.index('"stamp"') :]] = text
        return out

    v1 = by_stamp("v1")
    for other in ("v2", "v2_nonul", "v1_legacy", "v1_nonul"):
        same = set(by_stamp(other)) & set(v1)
        assert len(same) >= FRAMES_WANTED, other  # the same frames, byte for byte


def test_a_frame_too_big_for_the_limit_is_split_into_complete_messages(
    captured: Captured,
) -> None:
    parts: dict[tuple, list[dict]] = defaultdict(list)
    for doc in _frames(captured, "v1_split"):
        h = doc["header"]
        parts[(h["seq"], h["stamp"]["sec"], h["stamp"]["nsec"])].append(doc)
    whole = {
        (d["header"]["stamp"]["sec"], d["header"]["stamp"]["nsec"]): d["tracks"]
        for d in _frames(captured, "v1_legacy")
    }
    assert any(len(p) > 1 for p in parts.values())  # 7 people do not fit in 512 bytes
    compared = 0
    for (_seq, sec, nsec), docs in parts.items():
        if (sec, nsec) in whole:
            assert [t for d in docs for t in d["tracks"]] == whole[(sec, nsec)]
            compared += 1
    assert compared >= FRAMES_WANTED


# ----------------------------------------------- each client, with its documented settings


def _apply_everywhere(
    captured: Captured, client: str, rule: Callable[[bytes], Any]
) -> dict[str, list[Any]]:
    results = {}
    for name in sinks_for(client):
        results[name] = [rule(d) for d in captured.datagrams(name)]  # raises if it breaks
    return results


def test_optreceiver_reads_every_datagram(captured: Captured) -> None:
    for name, docs in _apply_everywhere(captured, "optreceiver.py", optreceiver).items():
        key = ROOT_KEY[SETTINGS[name].format]
        assert sum(bool(d.get(key)) for d in docs) >= FRAMES_WANTED
        assert all(key in d or "alive_IDs" in d for d in docs)


def test_optreceiver_needs_the_size_limit_for_a_big_crowd() -> None:
    crowd = [Track(i, i * 0.1, -i * 0.1, 0.9, 1.7, 0.1, 0.0, 12.5, 0.9) for i in range(1, 121)]
    (whole,) = encode_tracks(crowd, seq=1, stamp=1.5e9, fmt="opt-v1")
    assert len(whole) > 8192
    with pytest.raises(json.JSONDecodeError):
        optreceiver(whole)  # truncated by recvfrom(8192)
    parts = encode_tracks(crowd, seq=1, stamp=1.5e9, fmt="opt-v1", max_bytes=8192)
    assert len(parts) > 1
    assert [t["id"] for p in parts for t in optreceiver(p)["tracks"]] == list(range(1, 121))


def test_touchdesigner_udp_example_reads_every_datagram(captured: Captured) -> None:
    for name, frames in _apply_everywhere(captured, "udp_example.py", td_udp_example).items():
        assert sum(bool(f) for f in frames) >= FRAMES_WANTED, name
        assert all(set(t) == set(TRACK_KEYS) for f in frames for t in f)


def test_touchdesigner_udp_example_breaks_on_heartbeats_and_opt_v2(captured: Captured) -> None:
    beats = [d for d in captured.datagrams("v1") if is_heartbeat(d)]
    assert beats
    for data in beats:
        with pytest.raises(json.JSONDecodeError):
            td_udp_example(data)  # the slice is "{": not caught by the script
    frame = next(d for d in captured.datagrams("v2") if has_tracks(d))
    with pytest.raises(KeyError):
        td_udp_example(frame)


def test_node_ptrack_slice_gives_json_with_documented_settings(captured: Captured) -> None:
    for name in sinks_for("node-ptrack.js"):
        datagrams = captured.datagrams(name)
        results = node_ptrack(datagrams)
        assert len(results) == len(datagrams)
        for data, result in zip(datagrams, results, strict=True):
            assert result["error"] is None, result
            assert result["keys"] == ["header", "tracks"]
            assert result["out"].encode() == data.rstrip(b"\0")


def test_node_ptrack_forwards_a_lone_brace_for_a_heartbeat(captured: Captured) -> None:
    beats = [d for d in captured.datagrams("v1") if is_heartbeat(d)]
    for result in node_ptrack(beats):
        assert result["out"] == "{" and result["keys"] is None and "SyntaxError" in result["error"]


def test_node_ptrack_receives_the_multicast_stream(captured: Captured) -> None:
    if captured.multicast is None:
        pytest.skip("no node, or multicast to 224.0.0.1 does not come back on this host")
    received = captured.multicast
    assert sum('"id":' in r["out"] for r in received) == MULTICAST_COUNT
    for result in received:
        assert result["error"] is None and result["keys"] == ["header", "tracks"]
        assert result["bytes"] == len(result["out"].encode()) + 1  # the trailing NUL


def test_processing_sketch_reads_every_datagram(captured: Captured) -> None:
    for name, frames in _apply_everywhere(
        captured, "p5_opt_udp.pde", processing_p5_opt_udp
    ).items():
        assert sum(bool(f) for f in frames) >= FRAMES_WANTED, name


def test_processing_sketch_breaks_without_nul_on_heartbeats_and_on_opt_v2(
    captured: Captured,
) -> None:
    for data in captured.datagrams("v1_nonul"):
        with pytest.raises(json.JSONDecodeError):
            processing_p5_opt_udp(data)  # the final '}' was dropped instead of the NUL
    beats = [d for d in captured.datagrams("v1") if is_heartbeat(d)]
    assert beats
    for data in beats:
        with pytest.raises(KeyError):
            processing_p5_opt_udp(data)
    frame = next(d for d in captured.datagrams("v2") if has_tracks(d))
    with pytest.raises(KeyError):
        processing_p5_opt_udp(frame)


def test_max_parse_opt_reads_every_frame_and_ignores_heartbeats(captured: Captured) -> None:
    for name, outputs in _apply_everywhere(captured, "parseOPT.js", max_parse_opt).items():
        datagrams = captured.datagrams(name)
        for data, rows in zip(datagrams, outputs, strict=True):
            assert (rows is None) == is_heartbeat(data)
        rows = [r for out in outputs if out for r in out]
        assert len(rows) >= FRAMES_WANTED
        assert all(len(r) == 9 and type(r[0]) is int and type(r[8]) is int for r in rows)


def test_max_parse_opt_ignores_opt_v2(captured: Captured) -> None:
    assert all(max_parse_opt(d) is None for d in captured.datagrams("v2"))


def test_touchdesigner_opt_chop_gets_people_and_alive_ids(captured: Captured) -> None:
    for name in sinks_for("OPT_CHOP"):
        chop = OptChop()
        alive_rows = 0
        world_cooks = 0
        for group in cooks(captured.timed[name]):
            documents = [json_socket_reader(d) for d in group]
            chop.cook(documents)
            frames = [d for d in documents if d["header"]["frame_id"] == "world"]
            if not frames:
                continue
            world_cooks += 1
            last = max(frames, key=lambda d: d["header"]["seq"])
            for t in last["people_tracks"]:
                row = chop.rows[t["id"]]
                assert row["x"] == pytest.approx(t["x"], abs=1e-5)
                assert row["y"] == pytest.approx(t["y"], abs=1e-5)
                assert row["height"] == pytest.approx(t["height"], abs=1e-5)
                alive_rows += chop.is_alive(t["id"])
        assert chop.warnings == [], name
        assert world_cooks >= FRAMES_WANTED
        assert alive_rows >= FRAMES_WANTED  # heartbeats feed the isAlive channel
        assert chop.max_id is not None and chop.max_id >= 1


def test_touchdesigner_opt_chop_ignores_opt_v1(captured: Captured) -> None:
    chop = OptChop()
    for group in cooks(captured.timed["v1"]):
        chop.cook([json_socket_reader(d) for d in group])
    assert chop.rows == {}
    assert len(chop.warnings) >= FRAMES_WANTED
    assert chop.alive  # heartbeats still read


def test_generic_json_parsers_need_no_nul(captured: Captured) -> None:
    for name in sinks_for("generic JSON parser"):
        assert all(isinstance(strict_json(d.decode()), dict) for d in captured.datagrams(name))
    for data in captured.datagrams("v2")[:50]:
        with pytest.raises(json.JSONDecodeError, match="Extra data"):
            strict_json(data.decode())


# ------------------------------------------------------------- our own UDP examples


def _load(path: Path) -> Any:
    import importlib.util

    spec = importlib.util.spec_from_file_location(path.stem, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_our_udp_examples_read_every_sink(captured: Captured) -> None:
    receiver = _load(ROOT / "examples" / "python" / "udp_receiver.py")
    td = _load(ROOT / "examples" / "touchdesigner" / "udp_in_callbacks.py")
    for name in SINKS:
        frames = 0
        for data in captured.datagrams(name):
            (record,) = [receiver.normalise(o) for o in receiver.decode_objects(data)]
            tracks = td.parse_message(data)
            if is_heartbeat(data):
                assert record["kind"] == "heartbeat" and tracks is None
                assert td.parse_heartbeat(data) == record["alive_ids"]
                continue
            assert record["kind"] == "tracks" and record["format"] == SETTINGS[name].format
            assert [t["id"] for t in tracks] == sorted(t["id"] for t in record["tracks"])
            frames += bool(tracks)
        assert frames >= FRAMES_WANTED, name


# ------------------------------------------------------------------ library bugs found


def test_heartbeats_respect_max_datagram_bytes() -> None:
    from openptrack_py.messages import TrackBatch
    from openptrack_py.output.sinks import UdpJsonSink

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rx:
        rx.bind(("127.0.0.1", 0))
        rx.settimeout(2.0)
        cfg = UdpSinkConfig(host="127.0.0.1", port=rx.getsockname()[1], max_datagram_bytes=512)
        sink = UdpJsonSink(cfg)
        try:
            now = time.time()
            ids = tuple(range(10_000, 10_200))  # 200 live tracks, e.g. after a long run
            sink.send(TrackBatch(now, 1, alive_ids=ids, max_id=ids[-1]), now)
            sink.poll(now)  # the first heartbeat is due at once
            sizes = []
            while True:
                try:
                    sizes.append(len(rx.recv(65535)))
                except TimeoutError:
                    break
                rx.settimeout(0.2)
        finally:
            sink.close()
    assert len(sizes) >= 2  # the (empty) frame and at least one heartbeat
    assert max(sizes) <= cfg.max_datagram_bytes, sizes
