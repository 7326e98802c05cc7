"""Sources of depth frames behind one interface.

Every source yields :class:`~openptrack_py.detection.frame.Frame` objects in the camera's
optical frame (x right, y down, z forward, metres; NaN where the depth is invalid):

* :class:`FolderSource`: a folder written by :func:`record_folder`, a TUM RGB-D sequence,
  or a plain folder of depth PNGs;
* :class:`CloudSource`: a ``.pcd`` or ``.ply`` point cloud (or a folder of them);
* :class:`RealSenseBagSource`: a RealSense ``.bag`` recording;
* :class:`RealSenseSource` and :class:`AzureKinectSource`: live devices.

:func:`open_source` picks one from a text spec. open3d and OpenCV are imported only when a
source needs them, so importing this module costs nothing; without them the sources raise
:class:`~openptrack_py.errors.SourceError` saying how to install them.
"""

from __future__ import annotations

import bisect
import csv
import inspect
import json
import logging
import math
import re
import shutil
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from types import ModuleType, TracebackType
from typing import Any, NamedTuple, Protocol, TypeVar, runtime_checkable

import numpy as np

from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.errors import ConfigError, SourceError

__all__ = [
    "TUM_DEFAULT_INTRINSICS",
    "AzureKinectSource",
    "CloudSource",
    "FolderSource",
    "RealSenseBagSource",
    "RealSenseSource",
    "Source",
    "SourceError",
    "open_source",
    "read_cloud",
    "record_folder",
]

_log = logging.getLogger(__name__)

INSTALL_HINT = "pip install openptrack_py[sensor]"
#: Depth units per metre of our folder layout and of plain PNG folders (uint16 millimetres).
DEFAULT_DEPTH_SCALE = 1000.0
#: Depth units per metre of TUM RGB-D depth PNGs.
TUM_DEPTH_SCALE = 5000.0
#: Largest time difference, seconds, for a TUM colour image to belong to a depth image.
TUM_MAX_COLOR_DT = 0.02
#: The "ROS default" intrinsics the TUM RGB-D benchmark gives for its Freiburg sequences.
TUM_DEFAULT_INTRINSICS = Intrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
#: Frame rate assumed for the stamps of a plain folder of depth PNGs.
PLAIN_RATE_HZ = 30.0
#: Largest RMS reprojection residual, pixels, for an organised cloud to be read as an image.
MAX_PINHOLE_RESIDUAL_PX = 1.0
CLOUD_SUFFIXES = (".pcd", ".ply")
# Nominal horizontal field of view of the Azure Kinect colour camera (all resolutions).
_AZURE_KINECT_HFOV_DEG = 90.0

_ACCEPTED = (
    "a folder recorded by 'openptrack record-sensor', a TUM RGB-D folder (depth.txt, rgb.txt), "
    "a folder of depth PNGs with intrinsics.json, a .pcd/.ply file or a folder of them, "
    "a RealSense .bag, realsense[:SERIAL], azure-kinect[:N]"
)
_ANSI = re.compile(r"\x1b\[[0-9;]*m")
_CSV_FIELDS = ("seq", "stamp", "depth", "color", "intensity")

_S = TypeVar("_S", bound="_SourceBase")


# ------------------------------------------------------------------------ interface


@runtime_checkable
class Source(Protocol):
    """Anything that yields depth frames.

    Attributes
    ----------
    name : str
        What the source reads (a path or a device spec), for messages.
    intrinsics : Intrinsics or None
        Camera model of the frames; ``None`` for unorganised clouds (and, for a live
        device, before its first frame when the device does not report it).
    """

    name: str
    intrinsics: Intrinsics | None

    def frames(self) -> Iterator[Frame]:
        """Frames in order; ends at the end of a file or folder, never for a live device."""
        ...

    def close(self) -> None:
        """Release the file or device."""
        ...


class _SourceBase:
    """Context-manager support and a no-op :meth:`close` for the concrete sources."""

    name: str
    intrinsics: Intrinsics | None

    def frames(self) -> Iterator[Frame]:  # pragma: no cover - overridden
        """Frames in order."""
        raise NotImplementedError

    def close(self) -> None:
        """Release the source."""

    def __iter__(self) -> Iterator[Frame]:
        return self.frames()

    def __enter__(self: _S) -> _S:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


# ------------------------------------------------------------------------ helpers


def _import_open3d(what: str) -> ModuleType:
    try:
        import open3d
    except ImportError as exc:
        raise SourceError(
            f"{what}: needs open3d, which cannot be imported ({exc}); "
            f"install it with `{INSTALL_HINT}`"
        ) from None
    return open3d


def _import_cv2(what: str) -> ModuleType:
    try:
        import cv2
    except ImportError as exc:
        raise SourceError(
            f"{what}: needs OpenCV, which cannot be imported ({exc}); "
            f"install it with `{INSTALL_HINT}`"
        ) from None
    return cv2


def _clean(exc: BaseException) -> str:
    """An open3d exception's text without terminal colour codes."""
    return _ANSI.sub("", str(exc)).strip()


def _read_intrinsics_json(path: Path) -> tuple[Intrinsics, float | None]:
    """Intrinsics and the optional ``depth_scale`` of an ``intrinsics.json``."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SourceError(f"{path}: cannot read the intrinsics ({exc})") from None
    if not isinstance(data, dict):
        raise SourceError(f"{path}: expected a JSON object with width, height, fx, fy, cx, cy")
    try:
        intrinsics = Intrinsics.from_dict(data)
    except ConfigError as exc:
        raise SourceError(f"{path}: {exc}") from None
    scale = data.get("depth_scale")
    if scale is None:
        return intrinsics, None
    try:
        scale = float(scale)
    except (TypeError, ValueError):
        scale = math.nan
    if not (math.isfinite(scale) and scale > 0):
        raise SourceError(
            f"{path}: depth_scale must be a positive number of depth units per metre "
            f"(received {data['depth_scale']!r})"
        )
    return intrinsics, scale


def _read_image(cv2: ModuleType, path: Path, *, color: bool = False) -> np.ndarray:
    """An image file as stored (``color``: converted to 3-channel RGB)."""
    image = cv2.imread(str(path), cv2.IMREAD_COLOR if color else cv2.IMREAD_UNCHANGED)
    if image is None:
        raise SourceError(f"{path}: cannot read the image (missing, or not an image file)")
    if color:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
    return image


def _depth_to_metres(raw: np.ndarray, scale: float, origin: object) -> np.ndarray:
    """Float32 metres from integer depth codes; zero becomes NaN."""
    if raw.ndim == 3 and raw.shape[2] == 1:
        raw = raw[:, :, 0]
    if raw.ndim != 2:
        raise SourceError(f"{origin}: a depth image must have one channel (shape {raw.shape})")
    depth = raw.astype(np.float32) / np.float32(scale)
    depth[(raw == 0) | ~np.isfinite(depth)] = np.nan
    return depth


def _check_size(image: np.ndarray, intrinsics: Intrinsics | None, origin: object) -> None:
    if intrinsics is not None and image.shape[:2] != (intrinsics.height, intrinsics.width):
        raise SourceError(
            f"{origin}: image is {image.shape[1]}x{image.shape[0]} but the intrinsics are "
            f"{intrinsics.width}x{intrinsics.height}"
        )


def _rgb_uint8(colors: np.ndarray) -> np.ndarray:
    """open3d's float colours in [0, 1] as uint8 RGB."""
    return np.clip(np.rint(np.nan_to_num(colors) * 255.0), 0, 255).astype(np.uint8)


def _intrinsics_from_o3d(pinhole: Any, width: int = 0, height: int = 0) -> Intrinsics:
    """:class:`Intrinsics` from an ``open3d.camera.PinholeCameraIntrinsic``."""
    k = np.asarray(pinhole.intrinsic_matrix, dtype=float)
    return Intrinsics.from_matrix(k, pinhole.width or width, pinhole.height or height)


# --------------------------------------------------------------------- folder source


class _Entry(NamedTuple):
    seq: int
    stamp: float
    depth: Path
    color: Path | None
    intensity: Path | None


class FolderSource(_SourceBase):
    """Depth PNGs in a folder: our recordings, TUM RGB-D sequences, or plain PNGs.

    The layout is recognised from the folder's content:

    * **ours** (written by :func:`record_folder`): ``frames.csv`` (``seq,stamp,depth,color,
      intensity``, file names relative to the folder, empty when absent),
      ``intrinsics.json`` (:meth:`Intrinsics.to_dict` plus ``depth_scale``, depth units per
      metre, default 1000), ``depth/*.png`` uint16, optional ``color/*.png`` and
      ``intensity/*.png``;
    * **TUM RGB-D**: ``depth.txt`` and ``rgb.txt`` (lines ``timestamp filename``, ``#``
      comments), depth scale 5000 per metre; each depth image gets the colour image nearest
      in time if within 0.02 s. Intrinsics come from an ``intrinsics.json`` if present,
      else the benchmark's default (525, 525, 319.5, 239.5 at 640x480);
    * **plain**: ``*.png`` depth images (in the folder, or else in its ``depth/``), sorted
      by name, with an ``intrinsics.json``; stamp of frame *i* is ``i / rate`` (rate:
      ``rate_hz``, default 30).

    Parameters
    ----------
    path : str or Path
        The folder.
    loop : bool
        Start again at the end (stamps and sequence numbers keep increasing).
    rate_hz : float, optional
        Replay paced in real time at this rate; by default frames come as fast as they
        are read.

    Raises
    ------
    SourceError
        The folder is missing, of no known layout, has no frames, or a file in it is
        invalid (the message names the file); OpenCV is missing.
    """

    def __init__(
        self, path: str | Path, *, loop: bool = False, rate_hz: float | None = None
    ) -> None:
        self.path = Path(path)
        self.name = str(path)
        self.loop = bool(loop)
        if rate_hz is not None and not (math.isfinite(rate_hz) and rate_hz > 0):
            raise SourceError(
                f"{self.name}: rate_hz must be a positive number (received {rate_hz})"
            )
        self.rate_hz = rate_hz
        if not self.path.is_dir():
            raise SourceError(f"{self.name}: no such folder")
        self._cv2 = _import_cv2(self.name)
        self._closed = False
        if (self.path / "depth.txt").is_file() and (self.path / "rgb.txt").is_file():
            self.layout = "tum"
            self._entries = self._scan_tum()
        elif (self.path / "frames.csv").is_file():
            self.layout = "ours"
            self._entries = self._scan_ours()
        else:
            self.layout = "plain"
            self._entries = self._scan_plain()
        if not self._entries:
            raise SourceError(f"{self.name}: no frames ({self.layout} layout)")

    # -- layouts

    def _load_intrinsics(self, *, required: bool, default_scale: float) -> Intrinsics | None:
        file = self.path / "intrinsics.json"
        self._scale = default_scale
        if not file.is_file():
            if required:
                raise SourceError(
                    f"{self.name}: no intrinsics.json (needed for this layout: "
                    "width, height, fx, fy, cx, cy and optionally depth_scale)"
                )
            return None
        intrinsics, scale = _read_intrinsics_json(file)
        if scale is not None:
            self._scale = scale
        return intrinsics

    def _scan_ours(self) -> list[_Entry]:
        self.intrinsics = self._load_intrinsics(required=True, default_scale=DEFAULT_DEPTH_SCALE)
        file = self.path / "frames.csv"
        entries = []
        try:
            with file.open(newline="", encoding="utf-8") as fh:
                reader = csv.DictReader(fh)
                missing = {"seq", "stamp", "depth"} - set(reader.fieldnames or ())
                if missing:
                    raise SourceError(
                        f"{file}: header lacks {', '.join(sorted(missing))} "
                        f"(expected {','.join(_CSV_FIELDS)})"
                    )
                for row in reader:
                    try:
                        seq, stamp = int(row["seq"]), float(row["stamp"])
                    except (TypeError, ValueError):
                        raise SourceError(
                            f"{file}: line {reader.line_num}: seq and stamp must be numbers"
                        ) from None
                    if not row["depth"]:
                        raise SourceError(f"{file}: line {reader.line_num}: no depth file")
                    entries.append(
                        _Entry(
                            seq,
                            stamp,
                            self.path / row["depth"],
                            self.path / row["color"] if row.get("color") else None,
                            self.path / row["intensity"] if row.get("intensity") else None,
                        )
                    )
        except (OSError, UnicodeDecodeError, csv.Error) as exc:
            raise SourceError(f"{file}: cannot read ({exc})") from None
        return entries

    def _scan_tum(self) -> list[_Entry]:
        intrinsics = self._load_intrinsics(required=False, default_scale=TUM_DEPTH_SCALE)
        self.intrinsics = intrinsics or TUM_DEFAULT_INTRINSICS
        depth = _read_tum_list(self.path / "depth.txt")
        rgb = sorted(_read_tum_list(self.path / "rgb.txt"))
        rgb_stamps = [t for t, _ in rgb]
        entries = []
        for seq, (stamp, name) in enumerate(depth):
            color = None
            i = bisect.bisect_left(rgb_stamps, stamp)
            near = [j for j in (i - 1, i) if 0 <= j < len(rgb)]
            if near:
                j = min(near, key=lambda k: abs(rgb_stamps[k] - stamp))
                if abs(rgb_stamps[j] - stamp) <= TUM_MAX_COLOR_DT + 1e-9:
                    color = self.path / rgb[j][1]
            entries.append(_Entry(seq, stamp, self.path / name, color, None))
        return entries

    def _scan_plain(self) -> list[_Entry]:
        pngs = sorted(p for p in self.path.glob("*.png") if p.is_file())
        if not pngs and (self.path / "depth").is_dir():
            pngs = sorted(p for p in (self.path / "depth").glob("*.png") if p.is_file())
        if not pngs:
            raise SourceError(
                f"{self.name}: no depth images (expected frames.csv, depth.txt + rgb.txt, "
                "or *.png depth images with an intrinsics.json)"
            )
        self.intrinsics = self._load_intrinsics(required=True, default_scale=DEFAULT_DEPTH_SCALE)
        rate = self.rate_hz or PLAIN_RATE_HZ
        return [_Entry(i, i / rate, p, None, None) for i, p in enumerate(pngs)]

    # -- reading

    def _read(self, entry: _Entry, stamp_offset: float, seq_offset: int) -> Frame:
        cv2 = self._cv2
        raw = _read_image(cv2, entry.depth)
        if raw.dtype.kind not in "ui":
            raise SourceError(f"{entry.depth}: depth must be an integer image (is {raw.dtype})")
        depth = _depth_to_metres(raw, self._scale, entry.depth)
        _check_size(depth, self.intrinsics, entry.depth)
        color = intensity = None
        if entry.color is not None:
            color = _read_image(cv2, entry.color, color=True)
            _check_size(color, self.intrinsics, entry.color)
        if entry.intensity is not None:
            intensity = _read_image(cv2, entry.intensity)
            _check_size(intensity, self.intrinsics, entry.intensity)
        return Frame(
            stamp=entry.stamp + stamp_offset,
            seq=entry.seq + seq_offset,
            intrinsics=self.intrinsics,
            depth=depth,
            color=color,
            intensity=intensity,
        )

    def __len__(self) -> int:
        """Number of frames in one pass."""
        return len(self._entries)

    def frames(self) -> Iterator[Frame]:
        """The frames in order; forever when ``loop`` is set.

        Yields
        ------
        Frame
            Organised frames; depth in metres, NaN where the PNG holds zero.

        Raises
        ------
        SourceError
            A file listed by the folder cannot be read.
        """
        entries = self._entries
        stamps = [e.stamp for e in entries]
        steps = np.diff(stamps)
        step = float(np.median(steps)) if len(steps) else 1.0 / (self.rate_hz or PLAIN_RATE_HZ)
        lap_time = stamps[-1] - stamps[0] + step
        lap_seqs = entries[-1].seq - entries[0].seq + 1
        period = None if self.rate_hz is None else 1.0 / self.rate_hz
        start = time.monotonic()
        n = lap = 0
        while not self._closed:
            for entry in entries:
                if self._closed:
                    return
                if period is not None:
                    delay = start + n * period - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)
                yield self._read(entry, lap * lap_time, lap * lap_seqs)
                n += 1
            if not self.loop:
                return
            lap += 1

    def close(self) -> None:
        """Stop a looping replay."""
        self._closed = True


def _read_tum_list(path: Path) -> list[tuple[float, str]]:
    """``(timestamp, filename)`` lines of a TUM ``depth.txt`` or ``rgb.txt``."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SourceError(f"{path}: cannot read ({exc})") from None
    items = []
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        try:
            stamp = float(parts[0])
        except ValueError:
            stamp = math.nan
        if len(parts) < 2 or not math.isfinite(stamp):
            raise SourceError(f"{path}: line {lineno}: expected 'timestamp filename'")
        items.append((stamp, parts[1]))
    return items


# ---------------------------------------------------------------------- cloud source


class CloudSource(_SourceBase):
    """A point cloud file (``.pcd``, ``.ply``) or a folder of them, one frame per file.

    An organised PCD (``HEIGHT`` > 1, ``WIDTH x HEIGHT`` points, invalid points kept as NaN)
    becomes an organised frame: depth is the points' z, NaN where invalid, and the
    intrinsics are fitted by least squares to the valid points (``u = fx x / z + cx`` with
    ``u`` the column, likewise ``v``). A cloud whose points do not fit a pinhole camera
    (e.g. one transformed out of the camera frame), and every other cloud, becomes an
    unorganised frame with its finite ``points`` and, if present, ``point_colors``.

    Parameters
    ----------
    path : str or Path
        A ``.pcd``/``.ply`` file, or a folder whose ``.pcd``/``.ply`` files are read in name
        order.

    Raises
    ------
    SourceError
        Missing path, wrong extension, empty folder, unreadable cloud, or open3d missing.

    Notes
    -----
    The stamp of each frame is its file's modification time.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.name = str(path)
        if self.path.is_dir():
            self._files = sorted(
                p
                for p in self.path.iterdir()
                if p.is_file() and p.suffix.lower() in CLOUD_SUFFIXES
            )
            if not self._files:
                raise SourceError(f"{self.name}: no .pcd or .ply files in this folder")
        elif self.path.is_file():
            if self.path.suffix.lower() not in CLOUD_SUFFIXES:
                raise SourceError(f"{self.name}: not a point cloud file (expected .pcd or .ply)")
            self._files = [self.path]
        else:
            raise SourceError(f"{self.name}: no such file or folder")
        self._o3d = _import_open3d(self.name)
        self._first: Frame | None = read_cloud(self._files[0], seq=0, o3d=self._o3d)
        self.intrinsics = self._first.intrinsics

    def __len__(self) -> int:
        """Number of files."""
        return len(self._files)

    def frames(self) -> Iterator[Frame]:
        """One frame per file, in name order.

        Yields
        ------
        Frame
            Organised or unorganised, see the class description.
        """
        for seq, file in enumerate(self._files):
            frame = self._first if seq == 0 and self._first is not None else None
            self._first = None
            if frame is None:
                frame = read_cloud(file, seq=seq, o3d=self._o3d)
            self.intrinsics = frame.intrinsics
            yield frame


def read_cloud(path: str | Path, *, seq: int = 0, o3d: ModuleType | None = None) -> Frame:
    """Read one ``.pcd`` or ``.ply`` file as a frame (see :class:`CloudSource`).

    Parameters
    ----------
    path : str or Path
        The cloud file.
    seq : int
        Sequence number of the frame.
    o3d : module, optional
        The open3d module (imported when not given).

    Returns
    -------
    Frame
        Organised for an organised PCD that fits a pinhole camera, else unorganised.

    Raises
    ------
    SourceError
        The file cannot be read or holds no points.
    """
    path = Path(path)
    o3d = o3d or _import_open3d(str(path))
    try:
        cloud = o3d.io.read_point_cloud(
            str(path), remove_nan_points=False, remove_infinite_points=False
        )
    except RuntimeError as exc:
        raise SourceError(f"{path}: cannot read the point cloud ({_clean(exc)})") from None
    points = np.asarray(cloud.points, dtype=np.float64)
    if len(points) == 0:
        raise SourceError(f"{path}: no points read (not a valid point cloud file, or empty)")
    colors = _rgb_uint8(np.asarray(cloud.colors)) if cloud.has_colors() else None
    stamp = path.stat().st_mtime
    if path.suffix.lower() == ".pcd":
        width, height = _pcd_size(path)
        if height > 1 and width * height == len(points):
            frame = _organised_frame(points, colors, width, height, stamp, seq)
            if frame is not None:
                return frame
            _log.warning(
                "%s: organised cloud does not fit a pinhole camera in its own frame; "
                "read as unorganised points",
                path,
            )
    finite = np.isfinite(points).all(axis=1)
    return Frame(
        stamp=stamp,
        seq=seq,
        intrinsics=None,
        points=points[finite].astype(np.float32),
        point_colors=None if colors is None else colors[finite],
    )


def _pcd_size(path: Path) -> tuple[int, int]:
    """``(WIDTH, HEIGHT)`` from a PCD header; ``(0, 0)`` if absent or invalid."""
    header: dict[str, str] = {}
    try:
        with path.open("rb") as fh:
            for _ in range(100):
                raw = fh.readline(4096)
                if not raw:
                    break
                line = raw.decode("ascii", "replace").strip()
                if not line or line.startswith("#"):
                    continue
                key, _, value = line.partition(" ")
                header[key.upper()] = value.strip()
                if key.upper() == "DATA":
                    break
        return int(header.get("WIDTH", 0)), int(header.get("HEIGHT", 0))
    except (OSError, ValueError):
        return 0, 0


def _fit_axis(ratio: np.ndarray, pixel: np.ndarray) -> tuple[float, float] | None:
    """``(f, c)`` minimising ``|f ratio + c - pixel|``; ``None`` if ill-posed or a poor fit."""
    a = np.column_stack([ratio, np.ones_like(ratio)])
    solution, _, rank, _ = np.linalg.lstsq(a, pixel.astype(float), rcond=None)
    if rank < 2:
        return None
    f, c = float(solution[0]), float(solution[1])
    if not (math.isfinite(f) and f > 0 and math.isfinite(c)):
        return None
    rms = float(np.sqrt(np.mean((a @ solution - pixel) ** 2)))
    return (f, c) if rms <= MAX_PINHOLE_RESIDUAL_PX else None


def _organised_frame(
    points: np.ndarray,
    colors: np.ndarray | None,
    width: int,
    height: int,
    stamp: float,
    seq: int,
) -> Frame | None:
    grid = points.reshape(height, width, 3)
    valid = np.isfinite(grid).all(axis=2) & (grid[:, :, 2] > 0)
    if np.count_nonzero(valid) < 3:
        return None
    v, u = np.nonzero(valid)
    x, y, z = grid[valid].T
    fit_u = _fit_axis(x / z, u)
    fit_v = _fit_axis(y / z, v)
    if fit_u is None or fit_v is None:
        return None
    intrinsics = Intrinsics(width, height, fit_u[0], fit_v[0], fit_u[1], fit_v[1])
    depth = np.full((height, width), np.nan, dtype=np.float32)
    depth[valid] = z
    color = None if colors is None else colors.reshape(height, width, 3)
    return Frame(stamp=stamp, seq=seq, intrinsics=intrinsics, depth=depth, color=color)


# ------------------------------------------------------------------- RealSense, Azure


def _o3d_array(image: Any) -> np.ndarray:
    """The pixels of an open3d image (legacy or tensor API)."""
    return np.asarray(image.as_tensor().numpy() if hasattr(image, "as_tensor") else image)


def _o3d_depth_scale(meta: Any) -> float:
    """Depth units per metre of an open3d RealSense metadata (millimetres if unset)."""
    return float(meta.depth_scale) if meta.depth_scale > 0 else DEFAULT_DEPTH_SCALE


def _rgb_from_o3d(image: Any, color_format: str = "") -> np.ndarray | None:
    """uint8 RGB from an open3d colour image (either API); ``None`` if empty."""
    array = _o3d_array(image)
    if array.size == 0:
        return None
    if array.ndim == 2:
        array = np.repeat(array[:, :, None], 3, axis=2)
    array = array[:, :, :3]
    if color_format.upper().startswith("BGR"):
        array = array[:, :, ::-1]
    return np.ascontiguousarray(array, dtype=np.uint8)


def _depth_from_o3d(image: Any) -> np.ndarray | None:
    array = _o3d_array(image)
    if array.ndim == 3 and array.shape[2] == 1:
        array = array[:, :, 0]
    return None if array.size == 0 else array


class RealSenseBagSource(_SourceBase):
    """A RealSense ``.bag`` recording, read with ``open3d.t.io.RSBagReader``.

    Depth is aligned to the colour stream by the reader, so the intrinsics are the colour
    camera's. Stamps are the playback position, seconds from the start of the recording.

    Parameters
    ----------
    path : str or Path
        The ``.bag`` file.

    Raises
    ------
    SourceError
        The file is missing or not a RealSense recording with a depth and a colour stream
        (the message names the file), or open3d is missing.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.name = str(path)
        if not self.path.is_file():
            raise SourceError(f"{self.name}: no such file")
        o3d = _import_open3d(self.name)
        self._reader = o3d.t.io.RSBagReader()
        try:
            opened = self._reader.open(str(self.path))
        except RuntimeError as exc:
            raise SourceError(
                f"{self.name}: cannot open the RealSense recording ({_clean(exc)})"
            ) from None
        if not opened:
            raise SourceError(
                f"{self.name}: cannot open the RealSense recording (not a RealSense .bag, "
                "or it lacks a depth (Z16) or a colour stream)"
            )
        meta = self._reader.metadata
        try:
            self.intrinsics = _intrinsics_from_o3d(meta.intrinsics, meta.width, meta.height)
        except ConfigError as exc:
            self._reader.close()
            raise SourceError(
                f"{self.name}: invalid intrinsics in the recording ({exc})"
            ) from None
        self.depth_scale = _o3d_depth_scale(meta)
        self.fps = float(meta.fps)
        self._color_format = str(meta.color_format)
        self._open = True

    def frames(self) -> Iterator[Frame]:
        """The recording's frames until its end.

        Yields
        ------
        Frame
            Organised frames with depth in metres (NaN where zero) and RGB colour.
        """
        seq = 0
        while self._open and not self._reader.is_eof():
            try:
                rgbd = self._reader.next_frame()
            except RuntimeError as exc:
                raise SourceError(f"{self.name}: cannot read a frame ({_clean(exc)})") from None
            raw = _depth_from_o3d(rgbd.depth)
            if raw is None:  # the reader returns an empty image at the end
                continue
            stamp = self._reader.get_timestamp() / 1e6
            depth = _depth_to_metres(raw, self.depth_scale, self.name)
            color = _rgb_from_o3d(rgbd.color, self._color_format)
            yield Frame(stamp=stamp, seq=seq, intrinsics=self.intrinsics, depth=depth, color=color)
            seq += 1

    def close(self) -> None:
        """Close the recording."""
        if self._open:
            self._open = False
            self._reader.close()


class _LiveSource(_SourceBase):
    """A live device: frames stamped with the host's UNIX time at capture."""

    _open: bool

    def _capture(self) -> tuple[np.ndarray, np.ndarray | None] | None:
        """Depth (metres) and colour of the next capture; ``None`` when it had no depth."""
        raise NotImplementedError

    def frames(self) -> Iterator[Frame]:
        """Frames as the device delivers them, until :meth:`close`.

        Yields
        ------
        Frame
            Organised frames with depth in metres (NaN where zero) and RGB colour.
        """
        seq = 0
        while self._open:
            stamp = time.time()
            captured = self._capture()
            if captured is None:
                continue
            depth, color = captured
            yield Frame(stamp=stamp, seq=seq, intrinsics=self.intrinsics, depth=depth, color=color)
            seq += 1


class RealSenseSource(_LiveSource):
    """A live RealSense camera through ``open3d.t.io.RealSenseSensor``.

    Depth is aligned to colour; stamps are the host's UNIX time at capture, so frames of
    several sensors compare directly.

    Parameters
    ----------
    serial : str, optional
        Serial number of the camera; the first one found by default.
    config : mapping of str to str, optional
        Extra ``RealSenseSensorConfig`` entries (e.g. ``{"color_resolution": "640,480"}``).

    Raises
    ------
    SourceError
        No camera (or none with this serial) is connected, it cannot be started, or open3d
        is missing.
    """

    def __init__(
        self, serial: str | None = None, *, config: Mapping[str, str] | None = None
    ) -> None:
        self.serial = serial
        self.name = "realsense" + (f":{serial}" if serial else "")
        o3d = _import_open3d(self.name)
        sensor_cls = o3d.t.io.RealSenseSensor
        try:
            devices = sensor_cls.enumerate_devices()
        except RuntimeError as exc:
            raise SourceError(
                f"realsense: no RealSense device found (cannot list devices: {_clean(exc)})"
            ) from None
        serials = [str(getattr(d, "serial", "")) for d in devices]
        connected = ", ".join(s or "?" for s in serials) or "none"
        if not devices:
            raise SourceError(
                "realsense: no RealSense device found (connected: none); plug one in (USB 3) "
                "or replay a recording with a .bag file"
            )
        if serial is not None and serial not in serials:
            raise SourceError(
                f"realsense: no RealSense device with serial {serial} found "
                f"(connected: {connected})"
            )
        settings = dict(config or {})
        if serial is not None:
            settings["serial"] = serial
        self._sensor = sensor_cls()
        try:
            ok = self._sensor.init_sensor(o3d.t.io.RealSenseSensorConfig(settings), 0, "")
            ok = ok and self._sensor.start_capture(False)
        except RuntimeError as exc:
            raise SourceError(f"{self.name}: cannot start the camera ({_clean(exc)})") from None
        if not ok:
            raise SourceError(f"{self.name}: cannot start the camera (connected: {connected})")
        meta = self._sensor.get_metadata()
        self.intrinsics = _intrinsics_from_o3d(meta.intrinsics, meta.width, meta.height)
        self.depth_scale = _o3d_depth_scale(meta)
        self._color_format = str(meta.color_format)
        self._open = True

    def _capture(self) -> tuple[np.ndarray, np.ndarray | None] | None:
        try:
            rgbd = self._sensor.capture_frame(True, True)
        except RuntimeError as exc:
            raise SourceError(f"{self.name}: capture failed ({_clean(exc)})") from None
        raw = _depth_from_o3d(rgbd.depth)
        if raw is None:
            return None
        depth = _depth_to_metres(raw, self.depth_scale, self.name)
        return depth, _rgb_from_o3d(rgbd.color, self._color_format)

    def close(self) -> None:
        """Stop the capture."""
        if getattr(self, "_open", False):
            self._open = False
            self._sensor.stop_capture()


def _k4a_library_error() -> str | None:
    """Why the Azure Kinect SDK library cannot be loaded the way open3d loads it, or ``None``."""
    import ctypes
    import os
    import sys

    if sys.platform == "win32":
        name = "k4a.dll"
        folders = [os.environ.get("K4A_LIB_DIR", ""), ""]
    else:
        name = "libk4a.so"
        folders = ["", *(d for d in os.environ.get("LD_LIBRARY_PATH", "").split(":") if d)]
    reason = f"{name} not found"
    for folder in folders:
        try:
            ctypes.CDLL(os.path.join(folder, name) if folder else name)
        except OSError as exc:
            reason = str(exc)
        else:
            return None
    return reason


class AzureKinectSource(_LiveSource):
    """A live Azure Kinect through ``open3d.io.AzureKinectSensor`` (needs the k4a SDK).

    Depth is aligned to the colour camera. open3d does not expose the factory calibration,
    so unless ``intrinsics`` is given they are nominal (90 degree horizontal field of view,
    square pixels, centred principal point) for the delivered image size. Stamps are the
    host's UNIX time at capture.

    Parameters
    ----------
    device : int
        Index of the device.
    intrinsics : Intrinsics, optional
        Calibrated intrinsics of the colour camera at the delivered resolution.
    config : mapping of str to str, optional
        ``AzureKinectSensorConfig`` entries (e.g. ``{"color_resolution":
        "K4A_COLOR_RESOLUTION_720P"}``).

    Raises
    ------
    SourceError
        No device (or the SDK is not installed), or open3d is missing.
    """

    def __init__(
        self,
        device: int = 0,
        *,
        intrinsics: Intrinsics | None = None,
        config: Mapping[str, str] | None = None,
    ) -> None:
        self.device = int(device)
        self.name = f"azure-kinect:{self.device}"
        self.intrinsics = intrinsics
        o3d = _import_open3d(self.name)
        # Without the SDK, open3d's sensor object aborts the process when it is destroyed
        # (its destructor throws), so it must not be created at all.
        missing = _k4a_library_error()
        if missing is not None:
            raise SourceError(
                f"azure-kinect: no Azure Kinect device found (device {self.device}; the Azure "
                f"Kinect SDK library cannot be loaded: {missing}); install the SDK (libk4a) "
                "and connect a device"
            )
        try:
            sensor_config = o3d.io.AzureKinectSensorConfig(dict(config or {}))
            self._sensor = o3d.io.AzureKinectSensor(sensor_config)
            connected = self._sensor.connect(self.device)
        except RuntimeError as exc:
            raise SourceError(
                f"azure-kinect: no Azure Kinect device found (device {self.device}; {_clean(exc)})"
            ) from None
        if not connected:
            raise SourceError(
                f"azure-kinect: no Azure Kinect device found (device {self.device} did not "
                "connect); plug one in or check it is not in use"
            )
        self._open = True

    def _capture(self) -> tuple[np.ndarray, np.ndarray | None] | None:
        try:
            rgbd = self._sensor.capture_frame(True)
        except RuntimeError as exc:
            raise SourceError(f"{self.name}: capture failed ({_clean(exc)})") from None
        raw = None if rgbd is None else _depth_from_o3d(rgbd.depth)
        if raw is None:
            return None
        if raw.dtype.kind == "f":  # already metres
            depth = raw.astype(np.float32)
            depth[~(depth > 0)] = np.nan
        else:
            depth = _depth_to_metres(raw, DEFAULT_DEPTH_SCALE, self.name)
        if self.intrinsics is None:
            height, width = depth.shape
            fx = (width / 2) / math.tan(math.radians(_AZURE_KINECT_HFOV_DEG) / 2)
            self.intrinsics = Intrinsics(width, height, fx, fx, (width - 1) / 2, (height - 1) / 2)
        return depth, _rgb_from_o3d(rgbd.color)

    def close(self) -> None:
        """Disconnect the device."""
        if getattr(self, "_open", False):
            self._open = False
            self._sensor.disconnect()


# ----------------------------------------------------------------------- open_source


def open_source(
    spec: str | Path,
    *,
    extra: Mapping[str, Callable[[str], Source]] | None = None,
    **kw: Any,
) -> Source:
    """Open a source from a text spec.

    Parameters
    ----------
    spec : str or Path
        One of: a folder (:class:`FolderSource`, or :class:`CloudSource` if it holds only
        ``.pcd``/``.ply`` files), a ``.pcd``/``.ply`` file (:class:`CloudSource`), a
        ``.bag`` file (:class:`RealSenseBagSource`), ``realsense[:SERIAL]``
        (:class:`RealSenseSource`), ``azure-kinect[:N]`` (:class:`AzureKinectSource`), or
        ``PREFIX[:REST]`` for a prefix of ``extra``.
    extra : mapping of str to callable, optional
        More kinds: prefix to a factory called with the whole spec (e.g. ``{"sim":
        make_sim_source}`` for ``sim:scenario``). Checked before the built-in kinds.
    **kw
        Options passed to the source's constructor (e.g. ``loop``, ``rate_hz`` for a
        folder).

    Returns
    -------
    Source
        The opened source.

    Raises
    ------
    SourceError
        Naming the spec: a missing path, an unknown kind (listing the accepted ones), an
        option the source does not take, or the source's own error.
    """
    text = str(spec)
    kinds = dict(extra or {})
    accepted = _ACCEPTED + "".join(f", {prefix}:..." for prefix in kinds)
    head, sep, rest = text.partition(":")
    for prefix, factory in kinds.items():
        if head == prefix:
            return factory(text, **kw) if kw else factory(text)
    if head == "realsense":
        return _construct(RealSenseSource, text, rest or None, **kw)
    if head == "azure-kinect":
        try:
            index = int(rest) if sep else 0
        except ValueError:
            raise SourceError(
                f"open_source: {text!r}: the Azure Kinect index must be a number (azure-kinect:0)"
            ) from None
        return _construct(AzureKinectSource, text, index, **kw)
    path = Path(text).expanduser()
    if path.is_dir():
        if _is_cloud_folder(path):
            return _construct(CloudSource, text, path, **kw)
        return _construct(FolderSource, text, path, **kw)
    if not path.exists():
        raise SourceError(f"open_source: {text!r}: no such file or folder (accepted: {accepted})")
    suffix = path.suffix.lower()
    if suffix in CLOUD_SUFFIXES:
        return _construct(CloudSource, text, path, **kw)
    if suffix == ".bag":
        return _construct(RealSenseBagSource, text, path, **kw)
    raise SourceError(f"open_source: {text!r}: unknown kind of source (accepted: {accepted})")


def _is_cloud_folder(path: Path) -> bool:
    """A folder with clouds and none of the files that make a depth-image folder."""
    markers = ("frames.csv", "depth.txt", "intrinsics.json")
    if any((path / m).exists() for m in markers) or any(path.glob("*.png")):
        return False
    return any(p.suffix.lower() in CLOUD_SUFFIXES for p in path.iterdir())


def _construct(cls: type[_S], spec: str, *args: Any, **kw: Any) -> _S:
    try:
        inspect.signature(cls).bind(*args, **kw)
    except TypeError:
        raise SourceError(
            f"open_source: {spec!r}: option(s) {', '.join(sorted(kw))} do not apply to a "
            f"{cls.__name__}"
        ) from None
    return cls(*args, **kw)


# --------------------------------------------------------------------- record_folder


def _depth_to_mm(depth: np.ndarray) -> np.ndarray:
    mm = np.rint(np.nan_to_num(np.asarray(depth, dtype=np.float64), nan=0.0) * 1000.0)
    return np.clip(mm, 0, 65535).astype(np.uint16)


def _intensity_png(intensity: np.ndarray) -> np.ndarray:
    image = np.asarray(intensity)
    if image.dtype in (np.uint8, np.uint16):
        return image
    return np.clip(np.rint(np.nan_to_num(image.astype(np.float64))), 0, 65535).astype(np.uint16)


def record_folder(
    frames: Iterable[Frame],
    path: str | Path,
    *,
    max_frames: int | None = None,
    intrinsics: Intrinsics | None = None,
) -> int:
    """Write organised frames to a folder that :class:`FolderSource` replays.

    Depth is stored as uint16 millimetre PNGs (NaN and negatives as 0, clipped at
    65.535 m), colour as RGB PNGs (OpenCV writes them BGR on disk), intensity as 8 or 16 bit
    PNGs. ``frames.csv`` is written as frames arrive, so an interrupted recording is still
    readable; ``intrinsics.json`` holds the intrinsics and ``depth_scale`` 1000.

    Parameters
    ----------
    frames : iterable of Frame
        Organised frames (e.g. ``source.frames()``).
    path : str or Path
        Output folder; created if missing, must be empty if it exists.
    max_frames : int, optional
        Stop after this many frames.
    intrinsics : Intrinsics, optional
        Written to ``intrinsics.json``; by default those of the first frame.

    Returns
    -------
    int
        Number of frames written.

    Raises
    ------
    SourceError
        The folder is not empty or cannot be written, a frame is unorganised, has no
        intrinsics, or its images do not match them; OpenCV is missing.
    """
    out = Path(path)
    cv2 = _import_cv2(f"record {out}")
    if max_frames is not None and max_frames < 0:
        raise SourceError(f"record {out}: max_frames must be >= 0 (received {max_frames})")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise SourceError(f"record {out}: exists and is not an empty folder; choose a new one")
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SourceError(f"record {out}: cannot create the folder ({exc})") from None

    def write(rel: str, image: np.ndarray) -> str:
        target = out / rel
        target.parent.mkdir(exist_ok=True)
        if not cv2.imwrite(str(target), image):
            raise SourceError(f"record {out}: cannot write {rel}")
        return rel

    count = 0
    try:
        with (out / "frames.csv").open("w", newline="", encoding="utf-8") as fh:
            writer = csv.writer(fh, lineterminator="\n")
            writer.writerow(_CSV_FIELDS)
            fh.flush()
            if max_frames == 0:
                frames = ()
            for frame in frames:
                if frame.depth is None:
                    raise SourceError(
                        f"record {out}: frame {frame.seq} is an unorganised cloud; only depth "
                        "images can be recorded"
                    )
                if intrinsics is None:
                    intrinsics = frame.intrinsics
                    if intrinsics is None:
                        raise SourceError(f"record {out}: frame {frame.seq} has no intrinsics")
                if count == 0:
                    _write_intrinsics(out, intrinsics)
                origin = f"record {out}: frame {frame.seq}"
                _check_size(frame.depth, intrinsics, origin)
                name = f"{count:06d}.png"
                depth_rel = write(f"depth/{name}", _depth_to_mm(frame.depth))
                color_rel = intensity_rel = ""
                if frame.color is not None:
                    _check_size(frame.color, intrinsics, origin)
                    bgr = cv2.cvtColor(
                        np.ascontiguousarray(frame.color, np.uint8), cv2.COLOR_RGB2BGR
                    )
                    color_rel = write(f"color/{name}", bgr)
                if frame.intensity is not None:
                    _check_size(frame.intensity, intrinsics, origin)
                    intensity_rel = write(f"intensity/{name}", _intensity_png(frame.intensity))
                writer.writerow(
                    [frame.seq, repr(float(frame.stamp)), depth_rel, color_rel, intensity_rel]
                )
                fh.flush()
                count += 1
                if max_frames is not None and count >= max_frames:
                    break
    except BaseException:
        if count == 0:  # leave no half-made recording behind
            _remove_contents(out, remove_folder=created)
        raise
    if count == 0 and intrinsics is not None:
        _write_intrinsics(out, intrinsics)
    return count


def _write_intrinsics(folder: Path, intrinsics: Intrinsics) -> None:
    """``intrinsics.json`` of a recording: the intrinsics and our ``depth_scale``."""
    meta = {**intrinsics.to_dict(), "depth_scale": DEFAULT_DEPTH_SCALE}
    (folder / "intrinsics.json").write_text(json.dumps(meta, indent=1) + "\n")


def _remove_contents(folder: Path, *, remove_folder: bool) -> None:
    """Delete what :func:`record_folder` wrote into a folder that was empty or new."""
    if remove_folder:
        shutil.rmtree(folder, ignore_errors=True)
        return
    for child in folder.iterdir():
        if child.is_dir():
            shutil.rmtree(child, ignore_errors=True)
        else:
            child.unlink(missing_ok=True)
