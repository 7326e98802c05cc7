"""The ``security`` section: mutual TLS and access control for every Zenoh session.

With it, every node opens its Zenoh session with its own certificate (signed by the
site's authority, made by ``openptrack certs``) and refuses peers without one, and every
node enforces the same access-control list, so that only a sensor's node may put that
sensor's detections, only the tracker may put tracks and only an operator certificate
may change a node's configuration (:mod:`openptrack_py.security.policy`).
"""

from __future__ import annotations

from pathlib import Path

from pydantic import Field, field_validator

from openptrack_py.config.base import Name, StrictModel


class SecurityConfig(StrictModel):
    """Certificates and who may do what.

    Parameters
    ----------
    certs : Path
        Folder of the site's certificates: ``ca.pem`` (the site authority) and, for each
        identity on this machine, ``<identity>.pem`` and ``<identity>.key``. Relative
        paths are taken from the directory the command runs in.
    operators : list of str
        Certificate names allowed to change nodes' configuration (``openptrack config``);
        every command-line tool uses the identity ``operator`` unless
        ``--identity`` says otherwise.
    verify_names : bool
        Also check that a peer's certificate names the host it was reached at. Off by
        default: the peers' addresses are often not known when certificates are issued,
        and the site authority already authenticates every peer.
    """

    certs: Path
    operators: list[Name] = Field(default_factory=lambda: ["operator"], min_length=1)
    verify_names: bool = False

    @field_validator("certs")
    @classmethod
    def _expand(cls, value: Path) -> Path:
        return value.expanduser()
