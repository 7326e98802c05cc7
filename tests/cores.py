"""Independent CPU-bound runs of one test, spread over the machine's cores.

``make test`` runs test files side by side (one pytest-xdist worker per core), but the
long tail of the suite is a few heavy files; a test that needs several seeded
simulations (each a few seconds of pure computation) hands them to :func:`map_on_cores`
so that every core works on them, whichever worker runs it. Workers are spawned, not
forked: the test process may hold Zenoh sessions and their threads.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor
from typing import TypeVar

T = TypeVar("T")
R = TypeVar("R")


def map_on_cores(fn: Callable[[T], R], items: Iterable[T]) -> list[R]:
    """``[fn(item) for item in items]``, computed on up to ``os.cpu_count()`` processes.

    ``fn`` must be a module-level function (it is pickled by name); results come back in
    the order of ``items``. One item, or one core, runs in this process.
    """
    todo = list(items)
    workers = min(len(todo), os.cpu_count() or 1)
    if workers <= 1:
        return [fn(item) for item in todo]
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        return list(pool.map(fn, todo))
