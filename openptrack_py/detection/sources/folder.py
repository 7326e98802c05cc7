"""Folders of depth PNGs: our recordings, TUM RGB-D sequences and plain image folders.

:class:`FolderSource` recognises the layout from the folder's content (see its
docstring); :func:`~openptrack_py.detection.sources.recording.record_folder` writes the
first of them.
"""

from __future__ import annotations

import bisect
import csv
import json
import math
import time
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import NamedTuple

import numpy as np

from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.detection.sources.base import (
    DEFAULT_DEPTH_SCALE,
    _check_size,
    _depth_to_metres,
    _import_cv2,
    _SourceBase,
)
from openptrack_py.errors import ConfigError, SourceError

#: Depth units per metre of TUM RGB-D depth PNGs.
TUM_DEPTH_SCALE = 5000.0
#: Largest time difference, seconds, for a TUM colour image to belong to a depth image.
TUM_MAX_COLOR_DT = 0.02
#: The "ROS default" intrinsics the TUM RGB-D benchmark gives for its Freiburg sequences.
TUM_DEFAULT_INTRINSICS = Intrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
#: Frame rate assumed for the stamps of a plain folder of depth PNGs.
PLAIN_RATE_HZ = 30.0

# Columns of ``frames.csv`` in our layout (read here, written by ``record_folder``).
_CSV_FIELDS = ("seq", "stamp", "depth", "color", "intensity")


class _Entry(NamedTuple):
    seq: int
    stamp: float
    depth: Path
    color: Path | None
    intensity: Path | None


class FolderSource(_SourceBase):
    """Depth PNGs in a folder: our recordings, TUM RGB-D sequences, or plain PNGs.

    The layout is recognised from the folder's content:

    * **ours** (written by :func:`~.recording.record_folder`): ``frames.csv``
      (``seq,stamp,depth,color,intensity``, file names relative to the folder, empty when
      absent), ``intrinsics.json`` (:meth:`Intrinsics.to_dict` plus ``depth_scale``, depth
      units per metre, default 1000), ``depth/*.png`` uint16, optional ``color/*.png`` and
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
