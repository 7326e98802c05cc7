"""What every config section shares: strict models, names, endpoint checks.

:class:`StrictModel` is the base of every section: unknown keys are errors, values are
immutable and finite, and YAML booleans are not numbers. :data:`Name` is the type of
identifiers that become Zenoh key chunks; :func:`check_endpoint` validates a Zenoh
endpoint string.
"""

from __future__ import annotations

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


def check_endpoint(value: str) -> str:
    """Return ``value`` if it is a Zenoh endpoint ``<protocol>/<address>``.

    Raises
    ------
    ValueError
        Naming the form expected and the protocols allowed.
    """
    protocol, sep, address = value.partition("/")
    if not sep or protocol not in ENDPOINT_PROTOCOLS or not address:
        raise ValueError(
            f"must be a Zenoh endpoint '<protocol>/<address>' with protocol one of "
            f"{', '.join(ENDPOINT_PROTOCOLS)}, e.g. 'tcp/127.0.0.1:7447'"
        )
    return value
