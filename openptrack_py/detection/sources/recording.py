"""Recording frames to a folder that :class:`~.folder.FolderSource` replays."""

from __future__ import annotations

import csv
import json
import shutil
from collections.abc import Iterable
from pathlib import Path
from types import ModuleType

import numpy as np

from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.detection.sources.base import DEFAULT_DEPTH_SCALE, _check_size, _import_cv2
from openptrack_py.detection.sources.folder import _CSV_FIELDS
from openptrack_py.errors import SourceError


def record_folder(
    frames: Iterable[Frame],
    path: str | Path,
    *,
    max_frames: int | None = None,
    intrinsics: Intrinsics | None = None,
) -> int:
    """Write organised frames to a folder that :class:`~.folder.FolderSource` replays.

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
    created = _make_empty_folder(out)
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
                writer.writerow(_write_images(cv2, out, frame, intrinsics, f"{count:06d}.png"))
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


def _make_empty_folder(out: Path) -> bool:
    """Create the recording folder, or accept an empty one; whether it was created."""
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise SourceError(f"record {out}: exists and is not an empty folder; choose a new one")
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SourceError(f"record {out}: cannot create the folder ({exc})") from None
    return created


def _write_images(
    cv2: ModuleType, out: Path, frame: Frame, intrinsics: Intrinsics, name: str
) -> list[object]:
    """Write a frame's images as ``name`` in their folders; its ``frames.csv`` row."""
    origin = f"record {out}: frame {frame.seq}"
    _check_size(frame.depth, intrinsics, origin)
    depth_rel = _write_png(cv2, out, f"depth/{name}", _depth_to_mm(frame.depth))
    color_rel = intensity_rel = ""
    if frame.color is not None:
        _check_size(frame.color, intrinsics, origin)
        bgr = cv2.cvtColor(np.ascontiguousarray(frame.color, np.uint8), cv2.COLOR_RGB2BGR)
        color_rel = _write_png(cv2, out, f"color/{name}", bgr)
    if frame.intensity is not None:
        _check_size(frame.intensity, intrinsics, origin)
        intensity_rel = _write_png(cv2, out, f"intensity/{name}", _intensity_png(frame.intensity))
    return [frame.seq, repr(float(frame.stamp)), depth_rel, color_rel, intensity_rel]


def _write_png(cv2: ModuleType, out: Path, rel: str, image: np.ndarray) -> str:
    """Write ``image`` to ``out / rel`` (creating its folder); ``rel``."""
    target = out / rel
    target.parent.mkdir(exist_ok=True)
    if not cv2.imwrite(str(target), image):
        raise SourceError(f"record {out}: cannot write {rel}")
    return rel


def _depth_to_mm(depth: np.ndarray) -> np.ndarray:
    mm = np.rint(np.nan_to_num(np.asarray(depth, dtype=np.float64), nan=0.0) * 1000.0)
    return np.clip(mm, 0, 65535).astype(np.uint16)


def _intensity_png(intensity: np.ndarray) -> np.ndarray:
    image = np.asarray(intensity)
    if image.dtype in (np.uint8, np.uint16):
        return image
    return np.clip(np.rint(np.nan_to_num(image.astype(np.float64))), 0, 65535).astype(np.uint16)


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
