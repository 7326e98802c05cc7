"""Giving memory back to the operating system after a burst.

glibc keeps the heap a burst of allocations grew (a flood of large batches, a crowd
passing) and reuses it, so a node's resident memory stays at its peak long after the
burst. :func:`release_memory` asks glibc to return the free top and whole free pages of
its heaps (``malloc_trim``); elsewhere (musl, macOS) it does nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools


@functools.cache
def _malloc_trim() -> object | None:
    name = ctypes.util.find_library("c")
    if name is None:
        return None
    try:
        return getattr(ctypes.CDLL(name), "malloc_trim", None)
    except OSError:
        return None


def release_memory() -> bool:
    """Return free heap memory to the operating system; whether it could be asked."""
    trim = _malloc_trim()
    if trim is None:
        return False
    trim(0)  # type: ignore[operator]
    return True
