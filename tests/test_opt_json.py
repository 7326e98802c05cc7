"""OpenPTrack UDP JSON: golden bytes, C++ number formatting, framing guarantees."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from openptrack_py.errors import WireFormatError
from openptrack_py.messages import Track, Visibility
from openptrack_py.output.opt_json import (
    encode_opt_heartbeat,
    encode_tracks,
    number,
    parse_datagram,
)

GOLDEN = Path(__file__).parent / "golden"
STAMP = 1441244414.25  # exactly representable: nsec = 250000000

TRACKS = (
    Track(id=170, x=0.740519, y=-3.21577, z=0.9, height=1.01898, vx=0.1, vy=0.0,
          age=79.4518, confidence=0.491777),
    Track(id=171, x=12.5, y=-0.0, z=0.8, height=1.7, vx=0.0, vy=0.0, age=0.0333333,
          confidence=1.0, visibility=Visibility.NOT_VISIBLE),
    Track(id=200, x=1234567.0, y=1.23e-05, z=1.0, height=1.83, vx=0.0, vy=0.0, age=3600.0,
          confidence=0.5, stable_id=4, identity="alice"),
)  # fmt: skip

CASES = {
    "opt_v2_tracks": lambda: encode_tracks(TRACKS, seq=123, stamp=STAMP),
    "opt_v1_tracks": lambda: encode_tracks(TRACKS, seq=123, stamp=STAMP, fmt="opt-v1"),
    "opt_v2_tracks_no_nul": lambda: encode_tracks(TRACKS, seq=7, stamp=STAMP, trailing_nul=False),
    "opt_v2_empty": lambda: encode_tracks((), seq=8, stamp=STAMP),
    "opt_heartbeat": lambda: [encode_opt_heartbeat([59, 60], 60, seq=5694, stamp=STAMP)],
    "opt_heartbeat_empty": lambda: [encode_opt_heartbeat([], 60, seq=5695, stamp=STAMP)],
}


@pytest.mark.parametrize("name", list(CASES), ids=list(CASES))
def test_golden_bytes(name: str) -> None:
    (datagram,) = CASES[name]()
    assert datagram == (GOLDEN / f"{name}.bin").read_bytes()


def test_the_golden_bytes_say_what_openptrack_says() -> None:
    v2 = (GOLDEN / "opt_v2_tracks.bin").read_bytes()
    assert v2.startswith(
        b'{"header":{"seq":123,"stamp":{"sec":1441244414,"nsec":250000000},"frame_id":"world"},'
        b'"people_tracks":[{"id":170,"x":0.740519,"y":-3.21577,"height":1.01898,"age":79.4518,'
        b'"confidence":0.491777},'
    )
    assert v2.endswith(b'"stable_id":4,"face_name":"alice"}]}\x00')
    assert b'"x":1.23457e+06,"y":1.23e-05' in v2  # C++ ostream's %g
    assert b'"y":-0,' in v2  # negative zero, as C++ writes it
    v1 = (GOLDEN / "opt_v1_tracks.bin").read_bytes()
    assert b'"tracks":[{"id":170' in v1 and b"stable_id" not in v1  # v1 has six fields
    hb = (GOLDEN / "opt_heartbeat.bin").read_bytes()
    assert hb == (
        b'{"header":{"seq":5694,"stamp":{"sec":1441244414,"nsec":250000000},'
        b'"frame_id":"heartbeat"},"alive_IDs":[59,60],"max_ID":60}\x00'
    )


VALUES = [0.0, -0.0, 1.0, -1.5, 0.740519, -3.21577, 1.018984, 79.45184, 0.1, 1 / 3, 2 / 3,
          1e-5, 1.23456789e-05, 123456.7, 1234567.0, 1e15, -9.87654321e-7, 100000.0, 999999.5,
          0.0001, 0.00001234]  # fmt: skip


def test_numbers_match_cplusplus_ostream(tmp_path: Path) -> None:
    compiler = shutil.which("g++")
    assert compiler, "g++ is needed to check the number format against C++"
    source = tmp_path / "fmt.cpp"
    source.write_text(
        "#include <iostream>\n#include <cstdlib>\n"
        "int main(int argc, char** argv) {\n"
        "  for (int i = 1; i < argc; ++i) std::cout << std::strtod(argv[i], nullptr) << '\\n';\n"
        "}\n"
    )
    binary = tmp_path / "fmt"
    subprocess.run([compiler, "-O0", "-o", str(binary), str(source)], check=True)
    args = [repr(v) for v in VALUES]
    out = subprocess.run([str(binary), *args], check=True, capture_output=True, text=True)
    assert out.stdout.splitlines() == [number(v) for v in VALUES]


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf], ids=str)
def test_never_nan(bad: float) -> None:
    with pytest.raises(WireFormatError, match="refusing"):
        number(bad)
    broken = Track(id=1, x=bad, y=0.0, z=0.0, height=1.7, vx=0, vy=0, age=1, confidence=1)
    with pytest.raises(WireFormatError):
        encode_tracks([broken], seq=1, stamp=STAMP)


finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
tracks = st.lists(
    st.builds(
        Track,
        id=st.integers(1, 2**31 - 1),
        x=finite,
        y=finite,
        z=finite,
        height=st.floats(0, 3),
        vx=finite,
        vy=finite,
        age=st.floats(0, 1e6),
        confidence=st.floats(0, 1),
        stable_id=st.none() | st.integers(0, 1000),
        identity=st.none() | st.text(max_size=12),
    ),
    max_size=60,
)


def _no_constants(token: str) -> object:
    raise ValueError(f"non-standard JSON constant {token}")


def strict_loads(text: str) -> object:
    """``json.loads`` that refuses ``NaN``/``Infinity``/``-Infinity`` tokens."""
    return json.loads(text, parse_constant=_no_constants)


def numbers(obj: object) -> Iterator[float]:
    """Every number in a decoded JSON value (booleans are not numbers)."""
    if isinstance(obj, dict):
        for value in obj.values():
            yield from numbers(value)
    elif isinstance(obj, list):
        for value in obj:
            yield from numbers(value)
    elif isinstance(obj, int | float) and not isinstance(obj, bool):
        yield obj


def test_the_number_check_rejects_non_finite_numbers_not_names() -> None:
    for bad in ('{"x":NaN}', '{"x":Infinity}', '{"x":-Infinity}'):
        with pytest.raises(ValueError, match="non-standard"):
            strict_loads(bad)
    assert not all(map(math.isfinite, numbers(strict_loads('{"x":[1e999]}'))))  # overflows
    assert list(numbers(strict_loads('{"face_name":"NaN","x":1.5,"ok":true}'))) == [1.5]


@settings(max_examples=120, deadline=None)
@example(  # a person called "NaN" is a string, not a number (once a flaky text check)
    tracks=[Track(1, 0.0, 0.0, 0.0, 1.7, 0.0, 0.0, 1.0, 1.0, stable_id=1, identity="NaN")],
    fmt="opt-v2",
    nul=True,
    max_bytes=600,
    stamp=0.0,
)
@given(
    tracks=tracks,
    fmt=st.sampled_from(["opt-v2", "opt-v1"]),
    nul=st.booleans(),
    max_bytes=st.integers(600, 65507),
    stamp=st.floats(0, 4e9),
)
def test_every_datagram_is_one_openptrack_object(
    tracks: list[Track], fmt: str, nul: bool, max_bytes: int, stamp: float
) -> None:
    datagrams = encode_tracks(
        tracks, seq=42, stamp=stamp, fmt=fmt, trailing_nul=nul, max_bytes=max_bytes
    )
    root = "people_tracks" if fmt == "opt-v2" else "tracks"
    seen = []
    for data in datagrams:
        assert len(data) <= max_bytes
        assert data.endswith(b"]}\x00" if nul else b"]}")
        assert data.count(b"\x00") == (1 if nul else 0)
        text = data.rstrip(b"\x00").decode()
        obj = strict_loads(text)  # exactly one standard JSON object: no NaN, no garbage
        assert all(math.isfinite(v) for v in numbers(obj))
        assert list(obj) == ["header", root]  # header first, the tracks array last
        assert text.startswith('{"header"')
        header = obj["header"]
        assert header["seq"] == 42 and header["frame_id"] == "world"
        assert all(isinstance(header["stamp"][k], int) for k in ("sec", "nsec"))
        assert 0 <= header["stamp"]["nsec"] < 1_000_000_000
        for item in obj[root]:
            assert isinstance(item["id"], int)
            assert list(item)[:6] == ["id", "x", "y", "height", "age", "confidence"]
            if fmt == "opt-v1":
                assert len(item) == 6
        seen += [item["id"] for item in obj[root]]
        assert parse_datagram(data) == obj
    assert seen == [t.id for t in tracks]  # split frames keep every track, in order


def test_a_track_too_big_for_the_datagram_limit_is_an_error() -> None:
    huge = Track(id=1, x=1, y=1, z=1, height=1, vx=0, vy=0, age=1, confidence=1,
                 stable_id=1, identity="x" * 600)  # fmt: skip
    with pytest.raises(ValueError, match="max_bytes=600"):
        encode_tracks([huge], seq=1, stamp=STAMP, max_bytes=600)


@pytest.mark.parametrize(
    "bad",
    [b"", b"\x00", b"{}", b'{"header":1}{"header":2}', b"[1]", b"\xff\xfe"],
    ids=["empty", "nul", "no-header", "two-objects", "array", "bytes"],
)
def test_parser_rejects_anything_else(bad: bytes) -> None:
    with pytest.raises(WireFormatError):
        parse_datagram(bad)
