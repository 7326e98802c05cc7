"""Per-node counters, published every few seconds on ``opt/<site>/stats/<node>``."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True, slots=True)
class NodeStats:
    """A snapshot of one node's counters.

    Parameters
    ----------
    node : str
        Node name.
    stamp : float
        Snapshot time, UNIX seconds.
    uptime_s : float
        Seconds since the node started.
    counters : dict of str to int
        Monotonic totals (``in``, ``out``, ``dropped``, ``malformed`` and node-specific
        ones).
    rates_hz : dict of str to float
        Per-second rate of each counter over the last reporting interval.
    timings_ms : dict of str to float
        Mean duration of named stages over the last interval, milliseconds.
    pid : int
        Operating-system process id.
    host : str
        Host name of the machine running the node.
    """

    node: str
    stamp: float
    uptime_s: float
    counters: dict[str, int] = field(default_factory=dict)
    rates_hz: dict[str, float] = field(default_factory=dict)
    timings_ms: dict[str, float] = field(default_factory=dict)
    pid: int = 0
    host: str = ""
