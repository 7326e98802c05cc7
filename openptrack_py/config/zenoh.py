"""The ``zenoh`` section: how a deployment's Zenoh sessions find each other."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator

from openptrack_py.config.base import StrictModel, check_endpoint


class ZenohConfig(StrictModel):
    """How this deployment's Zenoh sessions find each other.

    Every node is a Zenoh peer that listens on ``listen`` and connects to ``hub`` plus
    ``connect``. The launcher on ``hub_host`` listens on ``hub`` itself, so all nodes
    meet there and then link directly (peer gossip). Multicast scouting is off unless
    asked for, so nothing depends on the LAN's multicast set-up.

    Parameters
    ----------
    mode : {"peer", "client"}
        Zenoh session mode of every node.
    hub : str or None
        Rendezvous endpoint, e.g. ``tcp/192.168.1.10:7447``. ``None`` disables it.
    hub_host : str
        Host whose launcher listens on ``hub``.
    listen : list of str
        Each node's own listening endpoints (port 0 = any free port).
    connect : list of str
        Extra endpoints every node connects to (e.g. a zenohd router).
    multicast_scouting : bool
        Let sessions discover each other by UDP multicast as well.
    shared_memory : bool
        Let sessions on one host pass large messages through Zenoh's shared memory. Off:
        our messages are small, deployed sensors sit on other hosts, and a session that
        once received shared memory keeps its watchdog threads and buffers for good (in
        the tracker, 15 MiB after one burst of large local batches, never given back).
    config_file : Path, optional
        A Zenoh JSON5 configuration applied first; the keys above override it.
    """

    mode: Literal["peer", "client"] = "peer"
    hub: str | None = "tcp/127.0.0.1:7447"
    hub_host: str = "localhost"
    listen: list[str] = Field(default_factory=lambda: ["tcp/127.0.0.1:0"])
    connect: list[str] = Field(default_factory=list)
    multicast_scouting: bool = False
    shared_memory: bool = False
    config_file: Path | None = None

    def named_endpoints(
        self, listen: Sequence[str] | None = None, connect: Sequence[str] | None = None
    ) -> list[tuple[str, str]]:
        """Every endpoint with the key that gives it (``zenoh.hub``, ``zenoh.listen.0``...).

        ``listen`` and ``connect`` replace the configured ones (command-line flags).
        """
        named = [("zenoh.hub", self.hub)] if self.hub else []
        for key, endpoints in (
            ("zenoh.listen", self.listen if listen is None else listen),
            ("zenoh.connect", self.connect if connect is None else connect),
        ):
            named += [(f"{key}.{i}", e) for i, e in enumerate(endpoints)]
        return named

    @field_validator("hub")
    @classmethod
    def _hub_endpoint(cls, value: str | None) -> str | None:
        return None if value is None else check_endpoint(value)

    @field_validator("listen", "connect")
    @classmethod
    def _endpoints(cls, value: list[str]) -> list[str]:
        for item in value:
            check_endpoint(item)
        return value
