"""Transport: the :class:`Bus` protocol, :class:`ZenohBus` and :class:`MemoryBus`."""

from openptrack_py.transport.base import Bus, Closable, Publisher, Sample, wait_for_subscribers
from openptrack_py.transport.keys import SiteKeys, key_matches
from openptrack_py.transport.memory import MemoryBus, MemoryNetwork

__all__ = [
    "Bus",
    "Closable",
    "MemoryBus",
    "MemoryNetwork",
    "Publisher",
    "Sample",
    "SiteKeys",
    "ZenohBus",
    "key_matches",
    "wait_for_subscribers",
]


def __getattr__(name: str) -> object:
    # Zenoh is imported only when a real session is wanted.
    if name == "ZenohBus":
        from openptrack_py.transport.zenoh_bus import ZenohBus

        return ZenohBus
    raise AttributeError(name)
