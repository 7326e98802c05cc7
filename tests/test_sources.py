"""Depth sources: folder layouts, point clouds, devices without hardware, and the CLI."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

cv2 = pytest.importorskip("cv2")
o3d = pytest.importorskip("open3d")

from openptrack_py.detection.frame import Frame, Intrinsics  # noqa: E402
from openptrack_py.detection.sources import (  # noqa: E402
    TUM_DEFAULT_INTRINSICS,
    AzureKinectSource,
    CloudSource,
    FolderSource,
    RealSenseBagSource,
    RealSenseSource,
    Source,
    open_source,
    record_folder,
)
from openptrack_py.errors import OptError, SourceError  # noqa: E402
from tests.conftest import ROOT, python_env  # noqa: E402

INTR = Intrinsics(16, 12, 14.5, 13.25, 7.4, 5.6)


def _frames(n: int = 4, *, seed: int = 0) -> list[Frame]:
    rng = np.random.default_rng(seed)
    frames = []
    for i in range(n):
        depth = rng.uniform(0.4, 9.0, (INTR.height, INTR.width)).astype(np.float32)
        depth[rng.random(depth.shape) < 0.2] = np.nan
        color = rng.integers(0, 256, (INTR.height, INTR.width, 3), dtype=np.uint8)
        intensity = rng.integers(0, 65536, (INTR.height, INTR.width), dtype=np.uint16)
        frames.append(
            Frame(
                stamp=1_700_000_000.123456 + i / 30 + rng.uniform(0, 1e-3),
                seq=10 + i,
                intrinsics=INTR,
                depth=depth,
                color=color,
                intensity=intensity,
            )
        )
    return frames


def _same_depth(a: np.ndarray, b: np.ndarray, tol: float = 0.0005 + 1e-6) -> None:
    assert a.shape == b.shape and b.dtype == np.float32
    assert np.array_equal(np.isnan(a), np.isnan(b))
    valid = ~np.isnan(a)
    assert np.max(np.abs(a[valid] - b[valid])) <= tol


# ----------------------------------------------------------------------- our folders


def test_record_folder_round_trip(tmp_path: Path) -> None:
    frames = _frames()
    out = tmp_path / "rec"
    assert record_folder(frames, out) == len(frames)
    meta = json.loads((out / "intrinsics.json").read_text())
    assert meta["depth_scale"] == 1000
    assert Intrinsics.from_dict(meta) == INTR
    assert (out / "frames.csv").read_text().splitlines()[0] == "seq,stamp,depth,color,intensity"

    with FolderSource(out) as source:
        assert isinstance(source, Source)
        assert source.layout == "ours" and source.intrinsics == INTR and len(source) == 4
        back = list(source.frames())
    assert len(back) == len(frames)
    for a, b in zip(frames, back, strict=True):
        assert b.seq == a.seq
        assert abs(b.stamp - a.stamp) < 1e-6
        assert b.intrinsics == INTR and b.organised
        _same_depth(a.depth, b.depth)
        assert b.color.dtype == np.uint8 and np.array_equal(b.color, a.color)
        assert b.intensity.dtype == np.uint16 and np.array_equal(b.intensity, a.intensity)


def test_record_folder_limits_clips_and_refuses(tmp_path: Path) -> None:
    frames = _frames(5)
    big = frames[0].depth.copy()
    big[0, 0], big[0, 1] = 80.0, -1.0
    frames[0] = Frame(frames[0].stamp, frames[0].seq, INTR, depth=big)
    out = tmp_path / "rec"
    assert record_folder(iter(frames), out, max_frames=2) == 2
    first = next(FolderSource(out).frames())
    assert first.depth[0, 0] == pytest.approx(65.535) and np.isnan(first.depth[0, 1])
    assert first.color is None and first.intensity is None
    with pytest.raises(SourceError, match="not an empty folder"):
        record_folder(frames, out)
    cloud = Frame(0.0, 0, None, points=np.zeros((3, 3), np.float32))
    with pytest.raises(SourceError, match="unorganised"):
        record_folder([cloud], tmp_path / "cloud")
    assert not (tmp_path / "cloud").exists()  # nothing half-made is left behind


def test_folder_loop_and_pacing(tmp_path: Path) -> None:
    record_folder(_frames(3), tmp_path / "rec")
    source = FolderSource(tmp_path / "rec", loop=True, rate_hz=50.0)
    start = time.monotonic()
    it = source.frames()
    got = [next(it) for _ in range(7)]
    elapsed = time.monotonic() - start
    source.close()
    assert elapsed >= 6 / 50 - 0.01
    stamps = [f.stamp for f in got]
    seqs = [f.seq for f in got]
    assert all(b > a for a, b in itertools.pairwise(stamps))
    assert seqs == [10, 11, 12, 13, 14, 15, 16]
    assert list(it) == []  # closed: the looping replay ends


# --------------------------------------------------------------------------- TUM


def _write_depth_png(path: Path, depth_m: np.ndarray, scale: float) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    raw = np.rint(np.nan_to_num(depth_m) * scale).astype(np.uint16)
    assert cv2.imwrite(str(path), raw)


def test_tum_layout(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    h, w = TUM_DEFAULT_INTRINSICS.height, TUM_DEFAULT_INTRINSICS.width
    stamps = [1305031102.160407, 1305031102.194330, 1305031102.226738]
    depths, colors = [], []
    depth_lines = ["# depth maps", "# file: 'freiburg1_xyz.bag'", "# timestamp filename"]
    rgb_lines = ["# color images", "# timestamp filename"]
    rgb_offsets = [0.011, -0.004, 0.05]  # the last one is too far: not associated
    for t, dt in zip(stamps, rgb_offsets, strict=True):
        depth = rng.uniform(0.5, 5.0, (h, w)).astype(np.float32)
        depth[:10, :10] = np.nan
        depths.append(depth)
        _write_depth_png(tmp_path / f"depth/{t:.6f}.png", depth, 5000.0)
        depth_lines.append(f"{t:.6f} depth/{t:.6f}.png")
        color = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        colors.append(color)
        ct = t + dt
        assert cv2.imwrite(str(tmp_path / f"rgb_{ct:.6f}.png"), color[:, :, ::-1])
        rgb_lines.append(f"{ct:.6f} rgb_{ct:.6f}.png")
    (tmp_path / "depth.txt").write_text("\n".join(depth_lines) + "\n")
    (tmp_path / "rgb.txt").write_text("\n".join(reversed(rgb_lines)) + "\n")

    source = open_source(str(tmp_path))
    assert isinstance(source, FolderSource) and source.layout == "tum"
    assert source.intrinsics == TUM_DEFAULT_INTRINSICS
    frames = list(source.frames())
    assert [f.seq for f in frames] == [0, 1, 2]
    for frame, t, depth in zip(frames, stamps, depths, strict=True):
        assert frame.stamp == pytest.approx(t, abs=1e-6)
        _same_depth(depth, frame.depth, tol=0.0001 + 1e-6)
    assert np.array_equal(frames[0].color, colors[0])
    assert np.array_equal(frames[1].color, colors[1])
    assert frames[2].color is None


def test_tum_layout_with_intrinsics_json(tmp_path: Path) -> None:
    depth = np.full((INTR.height, INTR.width), 2.0, np.float32)
    _write_depth_png(tmp_path / "d.png", depth, 5000.0)
    (tmp_path / "depth.txt").write_text("5.0 d.png\n")
    (tmp_path / "rgb.txt").write_text("# no colour\n")
    (tmp_path / "intrinsics.json").write_text(json.dumps(INTR.to_dict()))
    (frame,) = FolderSource(tmp_path).frames()
    assert frame.intrinsics == INTR and frame.stamp == 5.0 and frame.color is None
    assert np.allclose(frame.depth, 2.0)


# ------------------------------------------------------------------------- plain


def test_plain_png_folder(tmp_path: Path) -> None:
    depths = [np.full((INTR.height, INTR.width), 1.0 + i, np.float32) for i in range(3)]
    for i, d in enumerate(depths):
        d[2, 3] = np.nan
        _write_depth_png(tmp_path / f"img_{i:03d}.png", d, 1000.0)
    with pytest.raises(SourceError, match=r"intrinsics\.json"):
        FolderSource(tmp_path)
    (tmp_path / "intrinsics.json").write_text(json.dumps(INTR.to_dict()))
    source = FolderSource(tmp_path)
    assert source.layout == "plain"
    frames = list(source.frames())
    assert [f.stamp for f in frames] == pytest.approx([0.0, 1 / 30, 2 / 30])
    for frame, d in zip(frames, depths, strict=True):
        _same_depth(d, frame.depth)
    assert [f.stamp for f in FolderSource(tmp_path, rate_hz=200).frames()] == pytest.approx(
        [0.0, 0.005, 0.01]
    )


def test_folder_errors_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(SourceError, match="no depth images"):
        FolderSource(tmp_path)
    (tmp_path / "intrinsics.json").write_text('{"width": 4}')
    _write_depth_png(tmp_path / "a.png", np.ones((3, 4), np.float32), 1000.0)
    with pytest.raises(SourceError, match=r"intrinsics\.json.*'height'"):
        FolderSource(tmp_path)
    (tmp_path / "intrinsics.json").write_text(json.dumps(INTR.to_dict()))
    with pytest.raises(SourceError, match=r"a\.png: image is 4x3 but the intrinsics are 16x12"):
        list(FolderSource(tmp_path).frames())


# ------------------------------------------------------------------------- clouds


def _write_organised_pcd(path: Path, points: np.ndarray, width: int, height: int) -> None:
    header = [
        "VERSION .7",
        "FIELDS x y z",
        "SIZE 4 4 4",
        "TYPE F F F",
        "COUNT 1 1 1",
        f"WIDTH {width}",
        f"HEIGHT {height}",
        "VIEWPOINT 0 0 0 1 0 0 0",
        f"POINTS {width * height}",
        "DATA ascii",
    ]
    rows = [" ".join("nan" if np.isnan(c) else f"{c:.9g}" for c in p) for p in points]
    path.write_text("\n".join(header + rows) + "\n")


def test_organised_pcd_recovers_intrinsics(tmp_path: Path) -> None:
    w, h, fx, fy, cx, cy = 32, 24, 28.7, 27.9, 15.2, 11.9
    rng = np.random.default_rng(2)
    depth = rng.uniform(0.8, 6.0, (h, w)).astype(np.float32)
    depth[rng.random((h, w)) < 0.25] = np.nan
    v, u = np.mgrid[0:h, 0:w]
    points = np.stack([(u - cx) * depth / fx, (v - cy) * depth / fy, depth], axis=-1)
    path = tmp_path / "organised.pcd"
    _write_organised_pcd(path, points.reshape(-1, 3).astype(np.float32), w, h)

    source = open_source(str(path))
    assert isinstance(source, CloudSource)
    (frame,) = source.frames()
    assert frame.organised and frame.points is None
    k = frame.intrinsics
    assert (k.width, k.height) == (w, h)
    for got, want in ((k.fx, fx), (k.fy, fy), (k.cx, cx), (k.cy, cy)):
        assert got == pytest.approx(want, rel=1e-3)
    _same_depth(depth, frame.depth, tol=1e-5)
    assert frame.stamp == pytest.approx(path.stat().st_mtime)
    assert source.intrinsics == k


def test_organised_pcd_off_the_camera_frame_is_unorganised(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    points = rng.uniform(-2, 2, (6 * 5, 3)).astype(np.float32)
    points[4] = np.nan
    path = tmp_path / "world.pcd"
    _write_organised_pcd(path, points, 6, 5)
    frame = next(CloudSource(path).frames())
    assert not frame.organised and frame.intrinsics is None
    assert frame.points.shape == (29, 3) and frame.points.dtype == np.float32


def test_unorganised_ply_with_colours(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    points = rng.uniform(-3, 3, (50, 3))
    colors = rng.integers(0, 256, (50, 3), dtype=np.uint8)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.colors = o3d.utility.Vector3dVector(colors / 255.0)
    path = tmp_path / "cloud.ply"
    assert o3d.io.write_point_cloud(str(path), cloud)

    (frame,) = open_source(str(path)).frames()
    assert not frame.organised and frame.intrinsics is None and frame.depth is None
    assert frame.points.dtype == np.float32
    assert np.allclose(frame.points, points, atol=1e-5)
    assert frame.point_colors.dtype == np.uint8
    assert np.array_equal(frame.point_colors, colors)


def test_folder_of_clouds(tmp_path: Path) -> None:
    for i in range(3):
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.full((4, 3), float(i))))
        o3d.io.write_point_cloud(str(tmp_path / f"c{i}.pcd"), cloud)
    source = open_source(str(tmp_path))
    assert isinstance(source, CloudSource)
    frames = list(source.frames())
    assert [f.seq for f in frames] == [0, 1, 2]
    assert [float(f.points[0, 0]) for f in frames] == [0.0, 1.0, 2.0]
    assert all(f.point_colors is None for f in frames)


def test_unreadable_cloud(tmp_path: Path) -> None:
    path = tmp_path / "bad.pcd"
    path.write_text("not a cloud\n")
    with pytest.raises(SourceError, match=r"bad\.pcd: no points"):
        CloudSource(path)


# -------------------------------------------------------------------- open_source


def test_open_source_errors_name_the_spec(tmp_path: Path) -> None:
    missing = str(tmp_path / "nowhere.pcd")
    with pytest.raises(SourceError) as info:
        open_source(missing)
    assert missing in str(info.value) and "no such file" in str(info.value)
    assert "realsense[:SERIAL]" in str(info.value) and ".bag" in str(info.value)

    odd = tmp_path / "notes.txt"
    odd.write_text("hello")
    with pytest.raises(SourceError) as info:
        open_source(str(odd))
    assert str(odd) in str(info.value) and "unknown kind" in str(info.value)
    assert "azure-kinect[:N]" in str(info.value)
    assert isinstance(info.value, OptError)

    with pytest.raises(SourceError, match="azure-kinect:x"):
        open_source("azure-kinect:x")


def test_open_source_options_and_extra_kinds(tmp_path: Path) -> None:
    record_folder(_frames(2), tmp_path / "rec")
    source = open_source(tmp_path / "rec", loop=True)
    assert isinstance(source, FolderSource) and source.loop
    ply = tmp_path / "c.ply"
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ones((2, 3))))
    o3d.io.write_point_cloud(str(ply), cloud)
    with pytest.raises(SourceError, match="loop do not apply to a CloudSource"):
        open_source(str(ply), loop=True)

    seen = []

    def make(spec: str) -> Source:
        seen.append(spec)
        return FolderSource(tmp_path / "rec")

    assert isinstance(open_source("sim:crowd", extra={"sim": make}), FolderSource)
    assert seen == ["sim:crowd"]
    with pytest.raises(SourceError, match=r"sim:\.\.\."):
        open_source("nothing-here", extra={"sim": make})


def test_bag_errors_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(SourceError, match="no such file"):
        RealSenseBagSource(tmp_path / "missing.bag")
    bad = tmp_path / "garbage.bag"
    bad.write_bytes(b"not a rosbag")
    with pytest.raises(SourceError, match=r"garbage\.bag: cannot open the RealSense recording"):
        open_source(str(bad))


# ------------------------------------------------------------------------ devices


def test_realsense_without_a_device() -> None:
    if o3d.t.io.RealSenseSensor.enumerate_devices():
        pytest.skip("a RealSense camera is connected")
    expected = r"realsense: no RealSense device found \(connected: none\)"
    with pytest.raises(SourceError, match=expected):
        RealSenseSource()
    with pytest.raises(SourceError, match="no RealSense device"):
        open_source("realsense:0123456789")


def test_azure_kinect_without_a_device() -> None:
    try:
        source = AzureKinectSource(0)
    except SourceError as exc:
        assert "azure-kinect: no Azure Kinect device" in str(exc)
    else:  # pragma: no cover - only with hardware
        source.close()
        pytest.skip("an Azure Kinect is connected")
    with pytest.raises(SourceError, match="no Azure Kinect device"):
        open_source("azure-kinect:3")


def test_importing_sources_loads_neither_open3d_nor_cv2() -> None:
    code = (
        "import sys, openptrack_py.detection.sources; "
        "assert 'open3d' not in sys.modules and 'cv2' not in sys.modules"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=python_env(), cwd=ROOT
    )
    assert result.returncode == 0, result.stderr


# ---------------------------------------------------------------------------- CLI


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "openptrack_py.cli", *args],
        capture_output=True,
        text=True,
        timeout=120,
        env=python_env(),
        cwd=ROOT,
    )


def test_cli_record_sensor_round_trip(tmp_path: Path) -> None:
    frames = _frames(4)
    record_folder(frames, tmp_path / "src")
    out = tmp_path / "copy"
    result = _cli("record-sensor", str(tmp_path / "src"), str(out), "--frames", "3")
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == f"recorded 3 frames to {out}"
    back = list(FolderSource(out).frames())
    assert len(back) == 3
    for a, b in zip(frames, back, strict=False):
        assert b.seq == a.seq and abs(b.stamp - a.stamp) < 1e-6
        _same_depth(a.depth, b.depth)
        assert np.array_equal(a.color, b.color)

    out2 = tmp_path / "first-two"
    result = _cli("record-sensor", str(tmp_path / "src"), str(out2), "--seconds", "0.05")
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == f"recorded 2 frames to {out2}"


def test_cli_record_sensor_errors(tmp_path: Path) -> None:
    result = _cli("record-sensor", str(tmp_path / "nothing.bag"), str(tmp_path / "out"))
    assert result.returncode == 2
    assert result.stderr.startswith("openptrack record-sensor: open_source: ")
    assert "nothing.bag" in result.stderr and "no such file" in result.stderr
    assert not (tmp_path / "out").exists()

    ply = tmp_path / "cloud.ply"
    o3d.io.write_point_cloud(
        str(ply), o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ones((3, 3))))
    )
    result = _cli("record-sensor", str(ply), str(tmp_path / "out"))
    assert result.returncode == 2 and "unorganised cloud" in result.stderr
    assert not (tmp_path / "out").exists()

    help_text = _cli("record-sensor", "--help")
    assert help_text.returncode == 0 and help_text.stdout.startswith("usage: openptrack")
    assert "--frames N" in help_text.stdout and "--seconds S" in help_text.stdout
