"""Process runtime shared by every node: logging, counters, stats, inbox, flags."""

from openptrack_py.runtime.counters import Counters
from openptrack_py.runtime.logs import RateLimitedLog, configure_logging
from openptrack_py.runtime.node import Inbox, Node, Received

__all__ = ["Counters", "Inbox", "Node", "RateLimitedLog", "Received", "configure_logging"]
