"""What every config section shares: strict models, names, endpoint checks.

:class:`StrictModel` is the base of every section: unknown keys are errors, values are
immutable and finite, and YAML booleans are not numbers. :data:`Name` is the type of
identifiers that become Zenoh key chunks; :func:`check_endpoint` validates a Zenoh
endpoint string.
"""

from __future__ import annotations

import ipaddress
import re
import typing
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, field_validator

NAME_PATTERN = r"^[A-Za-z0-9_.\-]+$"
"""Identifiers (site, sensor ids, node names) become Zenoh key chunks: no '/', '*', '$'."""

Name = Annotated[str, Field(pattern=NAME_PATTERN, min_length=1, max_length=64)]
"""A site name, sensor id or node name: 1 to 64 characters matching :data:`NAME_PATTERN`."""

ENDPOINT_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream")
"""Protocols a Zenoh endpoint may name."""


def _is_numeric(annotation: Any) -> bool:
    if annotation in (int, float):
        return True
    return any(_is_numeric(a) for a in typing.get_args(annotation))


class StrictModel(BaseModel):
    """Base of every config section: unknown keys are errors, values are immutable.

    Numbers must be finite, and YAML booleans (``true``, ``yes``, ``on``) are not
    numbers.
    """

    model_config = ConfigDict(
        extra="forbid", frozen=True, validate_default=True, allow_inf_nan=False
    )

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_numbers(cls, value: Any, info: Any) -> Any:
        if isinstance(value, bool):
            field = cls.model_fields.get(info.field_name)
            if field is not None and _is_numeric(field.annotation):
                raise ValueError("must be a number, not true/false")
        return value


_HOSTNAME = re.compile(
    r"^(?=.{1,253}$)([A-Za-z0-9]([A-Za-z0-9\-]{0,61}[A-Za-z0-9])?)"
    r"(\.([A-Za-z0-9]([A-Za-z0-9\-]{0,61}[A-Za-z0-9])?))*\.?$"
)
NETWORK_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws")
"""Endpoint protocols whose address is ``host:port``."""


def check_endpoint(value: str) -> str:
    """Return ``value`` if it is a Zenoh endpoint ``<protocol>/<address>``.

    For network protocols the address must be ``host:port``: an IPv4 address, an IPv6
    address in brackets or a host name (RFC 1123), and a port in 0-65535 (0: any free
    port). Whether a name resolves is only known on the machine that uses it.

    Raises
    ------
    ValueError
        Naming the form expected, the protocols allowed, or what is wrong.
    """
    protocol, sep, address = value.partition("/")
    if not sep or protocol not in ENDPOINT_PROTOCOLS or not address:
        raise ValueError(
            f"must be a Zenoh endpoint '<protocol>/<address>' with protocol one of "
            f"{', '.join(ENDPOINT_PROTOCOLS)}, e.g. 'tcp/127.0.0.1:7447'"
        )
    if protocol in NETWORK_PROTOCOLS:
        host, port = split_host_port(address.split("#", 1)[0])
        if not 0 <= port <= 65535:
            raise ValueError(f"{value!r}: port must be in 0-65535, got {port}")
        check_host(host, value)
    return value


def split_host_port(address: str) -> tuple[str, int]:
    """``host:port`` (``[v6]:port`` for IPv6) as ``(host, port)``.

    Raises
    ------
    ValueError
        If there is no port or it is not a number.
    """
    host, sep, port = address.rpartition(":")
    if not sep or not host:
        raise ValueError(f"{address!r}: expected host:port, e.g. 127.0.0.1:7447")
    if not port.isdigit():
        raise ValueError(f"{address!r}: the port must be a number, got {port!r}")
    return host, int(port)


def check_host(host: str, where: str) -> str:
    """Return ``host`` if it is an IPv4 address, a bracketed IPv6 address or a host name."""
    if host.startswith("[") and host.endswith("]"):
        try:
            ipaddress.IPv6Address(host[1:-1])
        except ValueError:
            raise ValueError(f"{where!r}: {host} is not an IPv6 address") from None
        return host
    if host.replace(".", "").isdigit():
        try:
            ipaddress.IPv4Address(host)
        except ValueError:
            raise ValueError(f"{where!r}: {host} is not an IPv4 address") from None
        return host
    if not _HOSTNAME.match(host):
        raise ValueError(f"{where!r}: {host!r} is not a valid host name")
    return host
