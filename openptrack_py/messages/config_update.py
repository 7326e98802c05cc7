"""Live parameter updates of a node, and the node's answer."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True, slots=True)
class ConfigUpdate:
    """A request to change some of a node's parameters (or just to read them).

    Parameters
    ----------
    id : str
        Request id, echoed in the acknowledgement.
    set : dict
        Parameter name to new value; empty to only read the current parameters.
    """

    id: str
    set: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class ConfigAck:
    """A node's answer to a :class:`ConfigUpdate`.

    Parameters
    ----------
    id : str
        The request's id.
    node : str
        Node that answered.
    accepted : bool
        Whether the update was applied.
    error : str
        Why it was refused (empty when accepted).
    config : dict
        The parameters in force after the request.
    """

    id: str
    node: str
    accepted: bool
    error: str = ""
    config: dict[str, Any] = field(default_factory=dict)
