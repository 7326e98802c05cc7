"""Opening a source from a text spec: :func:`open_source` picks the kind and checks options."""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeVar

from openptrack_py.detection.sources.azure_kinect import AzureKinectSource
from openptrack_py.detection.sources.base import Source, _SourceBase
from openptrack_py.detection.sources.cloud import CLOUD_SUFFIXES, CloudSource
from openptrack_py.detection.sources.folder import FolderSource
from openptrack_py.detection.sources.realsense import RealSenseBagSource, RealSenseSource
from openptrack_py.errors import SourceError

_ACCEPTED = (
    "a folder recorded by 'openptrack record-sensor', a TUM RGB-D folder (depth.txt, rgb.txt), "
    "a folder of depth PNGs with intrinsics.json, a .pcd/.ply file or a folder of them, "
    "a RealSense .bag, realsense[:SERIAL], azure-kinect[:N]"
)

_S = TypeVar("_S", bound=_SourceBase)


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
