"""Point cloud files (``.pcd``, ``.ply``) as frames.

:func:`read_cloud` reads one file; an organised PCD whose points fit a pinhole camera
becomes a depth image with intrinsics recovered by least squares, any other cloud stays a
set of points. :class:`CloudSource` reads a file or a folder of them.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import numpy as np

from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.detection.sources.base import _clean, _import_open3d, _SourceBase
from openptrack_py.errors import SourceError

#: Largest RMS reprojection residual, pixels, for an organised cloud to be read as an image.
MAX_PINHOLE_RESIDUAL_PX = 1.0
#: File extensions read as point clouds.
CLOUD_SUFFIXES = (".pcd", ".ply")

_log = logging.getLogger(__name__)


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


def _rgb_uint8(colors: np.ndarray) -> np.ndarray:
    """open3d's float colours in [0, 1] as uint8 RGB."""
    return np.clip(np.rint(np.nan_to_num(colors) * 255.0), 0, 255).astype(np.uint8)
