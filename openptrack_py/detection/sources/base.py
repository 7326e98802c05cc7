"""What every depth source shares: the interface, the base classes and common helpers.

:class:`Source` is the interface the detector reads frames through; the concrete sources
derive from :class:`_SourceBase` (context manager, ``close``), and the live devices from
:class:`_LiveSource` (capture loop stamped with the host clock). The helpers here are
those several kinds of source use: importing the optional open3d and OpenCV with an
install hint, turning depth codes into metres, checking image sizes against the
intrinsics, and reading open3d images.
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from types import ModuleType, TracebackType
from typing import Any, Protocol, TypeVar, runtime_checkable

import numpy as np

from openptrack_py.detection.frame import Frame, Intrinsics
from openptrack_py.errors import SourceError

#: How to install the optional dependencies of the sources (open3d, OpenCV).
INSTALL_HINT = "pip install openptrack_py[sensor]"
#: Depth units per metre of our folder layout and of plain PNG folders (uint16 millimetres).
DEFAULT_DEPTH_SCALE = 1000.0

_ANSI = re.compile(r"\x1b\[[0-9;]*m")

_S = TypeVar("_S", bound="_SourceBase")


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


def _o3d_array(image: Any) -> np.ndarray:
    """The pixels of an open3d image (legacy or tensor API)."""
    return np.asarray(image.as_tensor().numpy() if hasattr(image, "as_tensor") else image)


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
