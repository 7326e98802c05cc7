"""``openptrack eval`` on files: ground truth, detections and tracks from anywhere.

The files are written by the tests (two people walking straight lines, seen by two noisy
"sensors"), then scored through the command line, as a user would.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
import orjson
import pytest

from openptrack_py.cli import main
from openptrack_py.eval.external import (
    DEFAULT_DISTANCE_M,
    ExternalFileError,
    TrackFileFeed,
    evaluate_files,
    read_detections,
    read_ground_truth,
    read_tracks,
)
from openptrack_py.eval.oracle import TruthFeed
from openptrack_py.messages import encode_detection_batch, encode_ground_truth, encode_track_batch
from openptrack_py.messages.ground_truth import GroundTruthFrame
from openptrack_py.messages.track import Track, TrackBatch
from openptrack_py.sim import build_scenario
from openptrack_py.sim.simulator import SensorFrame, Simulator, TruthFrame

RATE_HZ = 30.0
DURATION_S = 12.0


# -------------------------------------------------------------------------- the data


def _walkers(t: float) -> dict[int, tuple[float, float]]:
    """Two people crossing the room on parallel straight lines, 1.5 m apart."""
    return {1: (-3.0 + 0.5 * t, 0.0), 2: (3.0 - 0.4 * t, 1.5)}


def _times(rate_hz: float, phase_s: float = 0.0) -> Iterator[float]:
    for k in range(int(DURATION_S * rate_hz) + 1):
        yield round(phase_s + k / rate_hz, 6)


def _write_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[object]]) -> Path:
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(rows)
    return path


def _ground_truth(path: Path, origin_s: float = 50.0) -> Path:
    rows = [
        (origin_s + t, pid, f"{x:.4f}", f"{y:.4f}")
        for t in _times(RATE_HZ)
        for pid, (x, y) in _walkers(t).items()
    ]
    return _write_csv(path, ("time", "id", "x", "y"), rows)


def _detections(path: Path, origin_s: float = 50.0, seed: int = 0) -> Path:
    """Two sensors at 15 Hz, out of phase, 4 cm noise, a miss now and then."""
    rng = np.random.default_rng(seed)
    frames = []
    for sensor, phase in (("left", 0.0), ("right", 1 / 30)):
        for t in _times(15.0, phase):
            seen = [
                (x + rng.normal(0, 0.04), y + rng.normal(0, 0.04))
                for x, y in _walkers(t).values()
                if rng.random() > 0.05
            ]
            frames.append((t, sensor, seen))
    rows: list[tuple[object, ...]] = []
    for t, sensor, seen in sorted(frames, key=lambda f: f[0]):
        if not seen:
            rows.append((origin_s + t, sensor, "", "", ""))
        for x, y in seen:
            rows.append((origin_s + t, sensor, f"{x:.4f}", f"{y:.4f}", 0.9))
    return _write_csv(path, ("time", "sensor", "x", "y", "confidence"), rows)


def _tracks(path: Path, swap_at_s: float | None = None, origin_s: float = 50.0) -> Path:
    """Perfect tracks (ids 11, 12), optionally exchanging their ids from ``swap_at_s``."""
    rows = []
    for t in _times(RATE_HZ):
        for pid, (x, y) in _walkers(t).items():
            tid = 10 + pid
            if swap_at_s is not None and t >= swap_at_s:
                tid = 23 - tid
            rows.append((origin_s + t, tid, x, y))
    return _write_csv(path, ("time", "id", "x", "y"), rows)


def _eval(capsys: pytest.CaptureFixture[str], *args: object) -> tuple[int, object, str]:
    code = main(["eval", *map(str, args), "--format", "json"])
    out, err = capsys.readouterr()
    return code, (json.loads(out) if code == 0 else None), err


# ----------------------------------------------------------------- through the CLI


def test_our_tracker_on_csv_detections_from_two_sensors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    gt, dets = _ground_truth(tmp_path / "gt.csv"), _detections(tmp_path / "dets.csv")
    code, row, err = _eval(capsys, "--ground-truth", gt, "--detections", dets)
    assert code == 0, err
    assert isinstance(row, dict)
    assert row["tracker"] == "ukf" and row["detections"] == str(dets)
    assert row["sensors"] == 2 and row["batches"] == 2 * 181
    assert row["frames"] == 361 and row["gt_objects"] == 722 and row["gt_tracks"] == 2
    # the walkers (0.4-0.5 m/s) are confirmed once they have moved 0.5 m, about 1.1 s of
    # the 12 s: about 0.09 of MOTA; everything after that is tracked
    assert row["mota"] > 0.88 and row["idf1"] > 0.9 and row["motp"] < 0.1
    assert row["fp"] == 0 and row["fn"] < 0.12 * row["gt_objects"]
    assert row["id_switches"] == 0 and row["duplicates"] == 0 and row["duplicate_s"] == 0.0
    assert "seed" not in row and row["duration_s"] == pytest.approx(DURATION_S)


def test_the_oracle_on_files_scores_perfectly(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    gt, dets = _ground_truth(tmp_path / "gt.csv"), _detections(tmp_path / "dets.csv")
    code, row, err = _eval(
        capsys, "--ground-truth", gt, "--detections", dets, "--tracker", "truth"
    )
    assert code == 0, err
    assert isinstance(row, dict)
    assert (row["mota"], row["idf1"], row["duplicates"]) == (1.0, 1.0, 0)


def test_tracks_files_perfect_and_with_exchanged_ids(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    gt = _ground_truth(tmp_path / "gt.csv")
    perfect = _tracks(tmp_path / "perfect.csv")
    swapped = _tracks(tmp_path / "swapped.csv", swap_at_s=6.0)
    code, rows, err = _eval(capsys, "--ground-truth", gt, "--tracks", perfect, "--tracks", swapped)
    assert code == 0, err
    assert isinstance(rows, list)
    ok, bad = rows
    assert ok["tracker"] == "perfect.csv" and ok["tracks"] == str(perfect)
    assert (ok["mota"], ok["idf1"], ok["id_switches"], ok["fp"], ok["fn"]) == (1.0, 1.0, 0, 0, 0)
    assert bad["id_switches"] == 2 and bad["fp"] == bad["fn"] == 0
    assert bad["idf1"] == pytest.approx(0.5, abs=0.01)
    assert "batches" in bad and bad["sensors"] == 0


def test_our_tracker_and_a_tracks_file_in_one_table(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    gt, dets = _ground_truth(tmp_path / "gt.csv"), _detections(tmp_path / "dets.csv")
    theirs = _tracks(tmp_path / "theirs.csv", swap_at_s=6.0)
    args = ["eval", "--ground-truth", gt, "--detections", dets, "--tracks", theirs]
    assert main([str(a) for a in args]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].split()[:4] == ["tracker", "mota", "motp", "idf1"]
    assert "duplicates" in lines[0].split()
    assert [line.split()[0] for line in lines[1:]] == ["ukf", "theirs.csv"]


def test_tracks_at_their_own_rate_are_moved_along_their_velocity(tmp_path: Path) -> None:
    # a 10 Hz tracker with velocities scores like one at the ground truth's rate
    gt = _ground_truth(tmp_path / "gt.csv")
    rows = []
    for t in _times(10.0):
        for pid, (x, y) in _walkers(t).items():
            vx = 0.5 if pid == 1 else -0.4
            rows.append((50.0 + t, pid, x, y, vx, 0.0))
    tracks = _write_csv(tmp_path / "t.csv", ("time", "id", "x", "y", "vx", "vy"), rows)
    m = evaluate_files(gt, TrackFileFeed.from_file(tracks)).metrics
    assert m.mota == 1.0 and m.motp < 1e-4  # the ground truth is written to 0.1 mm


# ------------------------------------------------------------------------ recordings


def _recording(path: Path, duration_s: float = 10.0) -> tuple[Path, float]:
    """A simulated run written as ``openptrack node record`` writes it; returns its MOTA
    when the same run is scored in the simulator."""
    from openptrack_py.eval.trackers import run_eval

    scenario = build_scenario("crowd", seed=1, duration_s=duration_s)
    with path.open("wb") as out:
        for event in Simulator(scenario).events():
            if isinstance(event, SensorFrame):
                key, msg = f"opt/default/detections/{event.batch.sensor_id}", event.batch
                payload = encode_detection_batch(msg)
            else:
                key, payload = "opt/default/ground_truth", encode_ground_truth(event.frame)
            out.write(b'{"t":' + orjson.dumps(event.time) + b',"key":' + orjson.dumps(key))
            out.write(b',"msg":' + payload + b"}\n")
    return path, run_eval(scenario).metrics.mota


def test_a_recording_serves_as_ground_truth_and_detections(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    recording, simulated_mota = _recording(tmp_path / "run.jsonl")
    code, row, err = _eval(capsys, "--ground-truth", recording, "--detections", recording)
    assert code == 0, err
    assert isinstance(row, dict)
    assert row["sensors"] == 3 and row["frames"] == 301
    # 10 s of crowd: people are confirmed once they walk, the first second or two
    assert row["mota"] > 0.75 and row["mota"] == pytest.approx(simulated_mota, abs=0.005)
    assert row["duplicates"] == 0


def test_recorded_tracks_are_scored_and_smoothed_ones_ignored(tmp_path: Path) -> None:
    gt = _ground_truth(tmp_path / "gt.csv", origin_s=1.7e9)
    lines = []
    for k, t in enumerate(_times(RATE_HZ)):
        tracks = tuple(
            Track(id=10 + pid, x=x, y=y, z=0.9, height=1.7, vx=0.0, vy=0.0, age=t, confidence=1.0)
            for pid, (x, y) in _walkers(t).items()
        )
        for key in ("opt/default/tracks", "opt/default/tracks/smoothed"):
            far = key.endswith("smoothed")  # would be false positives if it were read
            batch = TrackBatch(
                stamp=1.7e9 + t + 0.01,
                seq=k,
                tracks=tuple(Track(**{**_fields(tr), "x": tr.x + 5.0 * far}) for tr in tracks),
            )
            lines.append(
                b'{"t":' + orjson.dumps(1.7e9 + t + 0.02) + b',"key":"' + key.encode() + b'",'
                b'"msg":' + encode_track_batch(batch) + b"}"
            )
    path = tmp_path / "tracks.jsonl"
    path.write_bytes(b"\n".join(lines) + b"\n")
    m = evaluate_files(gt, TrackFileFeed.from_file(path)).metrics
    assert m.fp == 0 and m.id_switches == 0
    assert m.fn == 2  # the first frame comes before the first output


def _fields(message: object) -> dict[str, object]:
    return {name: getattr(message, name) for name in message.__slots__}  # type: ignore[attr-defined]


# ---------------------------------------------------------------- readers, defaults


def test_detections_get_documented_defaults_and_empty_frames(tmp_path: Path) -> None:
    path = _write_csv(
        tmp_path / "d.csv",
        ("time", "sensor", "x", "y", "height", "arrival"),
        [(0.0, "a", 1.0, 2.0, "", ""), (0.0, "a", 3.0, 4.0, 1.2, ""), (0.1, "a", "", "", "", 0.3)],
    )
    first, second = read_detections(path, latency_s=0.05)
    d0, d1 = first.batch.detections
    assert (d0.confidence, d0.height, d0.z, d0.distance) == (1.0, 1.7, 0.85, DEFAULT_DISTANCE_M)
    assert (d1.height, d1.z) == (1.2, 0.6)
    assert first.time - first.capture_time == pytest.approx(0.05)
    assert second.batch.detections == () and second.batch.seq == 1
    assert second.time - second.capture_time == pytest.approx(0.2)


def test_json_lines_rows_are_read_like_csv(tmp_path: Path) -> None:
    path = tmp_path / "gt.jsonl"
    rows = [
        {"time": 0, "id": 1, "x": 0.0, "y": 0.0},
        {"time": 0, "id": 2, "x": 1.0, "y": 0.0, "covered": 0},
        {"time": 0.5, "id": None},
    ]
    path.write_text("\n".join(json.dumps(r) for r in rows) + "\n\n")
    a, b = read_ground_truth(path)
    assert [(p.id, p.covered) for p in a.frame.people] == [(1, True), (2, False)]
    assert b.frame.people == () and b.time - a.time == pytest.approx(0.5)


def test_ground_truth_frames_stream_without_reading_the_whole_file(tmp_path: Path) -> None:
    path = _ground_truth(tmp_path / "gt.csv")
    with path.open("a") as f:
        f.write("not,a,valid,row\n")
    frames = read_ground_truth(path)
    first = next(frames)  # the bad last line is not read yet
    assert isinstance(first, TruthFrame) and isinstance(first.frame, GroundTruthFrame)
    with pytest.raises(ExternalFileError, match=r"gt\.csv:724: time: expected a number"):
        list(frames)


# ------------------------------------------------------------------ malformed files

MALFORMED = [
    pytest.param(
        "gt.csv", "time,id,x,y\n0,1,0,0\n0.1,1,abc,0\n",
        "gt.csv:3: x: expected a number, got 'abc'", id="not-a-number",
    ),
    pytest.param(
        "gt.csv", "time,id,x,y,colour\n", "gt.csv:1: colour: unknown column", id="unknown-column"
    ),
    pytest.param("gt.csv", "time,id,x\n0,1,0\n", "gt.csv:1: y: missing column", id="no-column"),
    pytest.param(
        "gt.csv", "time,id,x,y\n0,1,0,0\n0,1,1,1\n", "gt.csv:3: id: person 1 appears twice",
        id="repeated-id",
    ),
    pytest.param(
        "gt.csv", "time,id,x,y\n1,1,0,0\n0,1,0,0\n", "gt.csv:3: time: frame at 0 s does not come",
        id="time-goes-back",
    ),
    pytest.param(
        "gt.csv", "time,id,x,y\n0,1.5,0,0\n", "gt.csv:2: id: expected an integer, got '1.5'",
        id="float-id",
    ),
    pytest.param(
        "gt.csv", "time,id,x,y\n1.7e12,1,0,0\n", "gt.csv:2: time: expected seconds in",
        id="milliseconds",
    ),
    pytest.param(
        "gt.csv", "time,id,x,y\n0,1,nan,0\n", "gt.csv:2: x: expected a finite number", id="nan"
    ),
    pytest.param(
        "gt.csv", "time,id,x,y\n0,1,0\n", "gt.csv:2: expected 4 cells, got 3", id="short"
    ),
    pytest.param("gt.txt", "time,id,x,y\n", "gt.txt: unknown format '.txt'", id="extension"),
    pytest.param(
        "gt.jsonl", '{"time": 0, "id": 1, "x": 0, "y": 0}\n{"time": 1, "id": 1, "x": 0, y}\n',
        "gt.jsonl:2: not valid JSON", id="bad-json",
    ),
    pytest.param(
        "gt.jsonl", '{"time": 0, "id": 1, "x": "0", "y": 0, "z": 1}\n',
        "gt.jsonl:1: z: unknown key", id="json-unknown-key",
    ),
    pytest.param(
        "gt.jsonl", '{"t": 1.0, "key": "opt/default/ground_truth", "msg": {"v": 1}}\n',
        "gt.jsonl:1: msg: kind: expected 'ground_truth'", id="bad-recording",
    ),
]  # fmt: skip


@pytest.mark.parametrize("name, text, message", MALFORMED)
def test_a_malformed_ground_truth_file_is_one_clear_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, text: str, message: str
) -> None:
    gt = tmp_path / name
    gt.write_text(text)
    tracks = _tracks(tmp_path / "tracks.csv")
    code, _, err = _eval(capsys, "--ground-truth", gt, "--tracks", tracks)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("openptrack eval: ")
    assert err.startswith(f"openptrack eval: {tmp_path}/{message}"), err


MALFORMED_DETECTIONS = [
    pytest.param(
        "time,sensor,x,y,confidence\n0,a,0,0,1.5\n",
        "dets.csv:2: confidence: expected a number in [0, 1], got 1.5", id="confidence",
    ),
    pytest.param(
        "time,sensor,x,y,distance\n0,a,0,0,-2\n",
        "dets.csv:2: distance: expected a number in [0, 10000], got -2.0", id="distance",
    ),
    pytest.param(
        "time,sensor,x,y\n0,my sensor,0,0\n",
        "dets.csv:2: sensor: expected only the characters [A-Za-z0-9_.-]", id="sensor-name",
    ),
    pytest.param(
        "time,sensor,x,y\n0,a,0,\n", "dets.csv:2: y: missing (give all of x, y or none)",
        id="half-position",
    ),
    pytest.param(
        "time,sensor,x,y\n0,a,0,0\n0,b,0,0\n0,a,1,1\n",
        "dets.csv:4: time: frame of sensor 'a' at 0 s does not come after", id="split-frame",
    ),
    pytest.param(
        "time,sensor,x,y\n5,a,0,0\n1,b,0,0\n",
        "dets.csv:3: time: frame arrives 4.000 s before the previous one", id="unsorted",
    ),
]  # fmt: skip


@pytest.mark.parametrize("text, message", MALFORMED_DETECTIONS)
def test_a_malformed_detections_file_is_one_clear_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, message: str
) -> None:
    gt = _ground_truth(tmp_path / "gt.csv", origin_s=0.0)
    dets = tmp_path / "dets.csv"
    dets.write_text(text)
    code, _, err = _eval(capsys, "--ground-truth", gt, "--detections", dets)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith(f"openptrack eval: {tmp_path}/{message}"), err


def test_a_malformed_tracks_file_names_its_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    gt = _ground_truth(tmp_path / "gt.csv", origin_s=0.0)
    tracks = tmp_path / "t.csv"
    tracks.write_text("time,id,x,y\n0,1,0,0\n0.5,x,0,0\n")
    code, _, err = _eval(capsys, "--ground-truth", gt, "--tracks", tracks)
    assert code == 2 and err == f"openptrack eval: {tracks}:3: id: expected an integer, got 'x'\n"


def test_a_missing_file_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tracks = _tracks(tmp_path / "t.csv")
    code, _, err = _eval(capsys, "--ground-truth", tmp_path / "nope.csv", "--tracks", tracks)
    assert code == 2 and f"{tmp_path}/nope.csv: cannot open" in err


@pytest.mark.parametrize(
    "args, message",
    [
        (["--ground-truth", "gt.csv"], "--ground-truth needs --detections or --tracks"),
        (["--detections", "d.csv"], "need --ground-truth"),
        (["--ground-truth", "g.csv", "--tracks", "t.csv", "--seed", "1"], "--seed apply to"),
        (["--ground-truth", "g.csv", "--tracks", "t.csv", "--set", "a=1"], "tracker options"),
    ],
)
def test_file_options_that_do_not_go_together(
    capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    code, _, err = _eval(capsys, *args)
    assert code == 2 and message in err


def test_reader_functions_are_lazy_about_errors_until_read(tmp_path: Path) -> None:
    missing = tmp_path / "none.csv"
    frames = read_tracks(missing)  # nothing opened yet
    with pytest.raises(ExternalFileError, match="cannot open"):
        next(frames)


def test_evaluate_files_with_the_oracle_counts_what_it_played(tmp_path: Path) -> None:
    gt, dets = _ground_truth(tmp_path / "gt.csv"), _detections(tmp_path / "dets.csv")
    result = evaluate_files(gt, TruthFeed(), detections=dets)
    assert result.batches == 362 and result.sensors == 2 and result.scenario == "gt.csv"
    assert result.metrics.mota == 1.0 and not math.isnan(result.metrics.motp)
