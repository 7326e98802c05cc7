"""The ``outputs`` section: smoother and sinks (UDP JSON, OSC, WebSocket and web view)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator, model_validator

from openptrack_py.config.base import Name, StrictModel
from openptrack_py.errors import ConfigError

MIN_TOKEN_CHARS = 16
"""Shortest web access token accepted."""


class SmootherConfig(StrictModel):
    """OpenPTrack's moving-average smoother, corrected (defaults: OpenPTrack v2).

    Parameters
    ----------
    rate_hz : float
        Output rate.
    window_size : int
        Positions averaged per track.
    position_lifetime_s : float
        Positions older than this leave the average.
    track_lifetime_s : float
        A track leaves the output this long after its last real detection
        (``track_lifetime_with_no_detections``).
    publish_empty : bool
        Send a frame every cycle even when no one is tracked; otherwise send an empty
        frame every ``heartbeat_interval_s`` only.
    heartbeat_interval_s : float
        Period of the empty frames when ``publish_empty`` is off.
    """

    rate_hz: float = Field(30.0, gt=0.0, le=240.0)
    window_size: int = Field(5, ge=1, le=100)
    position_lifetime_s: float = Field(0.6, gt=0.0, le=60.0)
    track_lifetime_s: float = Field(0.6, gt=0.0, le=60.0)
    publish_empty: bool = True
    heartbeat_interval_s: float = Field(1.0, gt=0.0, le=60.0)


class UdpSinkConfig(StrictModel):
    """One UDP JSON destination (OpenPTrack's ``ros2udp_converter``).

    Parameters
    ----------
    host : str
        Destination address: a host, a broadcast address (``x.x.x.255``) or a multicast
        group (``224.0.0.1``).
    port : int
        Destination port.
    mode : {"unicast", "broadcast", "multicast"}
        How to send.
    ttl : int
        Multicast time-to-live (hops).
    format : {"opt-v2", "opt-v1"}
        Root key ``people_tracks`` (v2, what the TouchDesigner component reads) or
        ``tracks`` (v1, what the Python, Processing, Max and Node examples read).
    trailing_nul : bool
        End each datagram with one NUL byte, as OpenPTrack does (the Processing example
        needs it; some Max externals break on it).
    heartbeat : bool
        Send ``alive_IDs`` / ``max_ID`` heartbeats (also when the room is empty).
    heartbeat_interval_s : float
        Heartbeat period.
    max_datagram_bytes : int
        Frames larger than this are split into several complete JSON messages with the
        same header (never two JSON objects in one datagram).
    """

    host: str = "127.0.0.1"
    port: int = Field(21234, ge=1, le=65535)
    mode: Literal["unicast", "broadcast", "multicast"] = "unicast"
    ttl: int = Field(1, ge=0, le=255)
    format: Literal["opt-v2", "opt-v1"] = "opt-v2"
    trailing_nul: bool = True
    heartbeat: bool = True
    heartbeat_interval_s: float = Field(0.25, gt=0.0, le=60.0)
    max_datagram_bytes: int = Field(65507, ge=512, le=65507)


class OscSinkConfig(StrictModel):
    """One OSC destination (python-osc).

    Parameters
    ----------
    host : str
        Destination address.
    port : int
        Destination port.
    prefix : str
        Address prefix: messages go to ``<prefix>/frame``, ``<prefix>/track`` and
        ``<prefix>/alive``.
    """

    host: str = "127.0.0.1"
    port: int = Field(7000, ge=1, le=65535)
    prefix: str = Field("/opt", pattern=r"^(/[A-Za-z0-9_\-]+)+$")


class WebConfig(StrictModel):
    """The WebSocket stream and the live web view.

    Parameters
    ----------
    host : str
        Address to listen on (``0.0.0.0`` to allow other machines).
    port : int
        HTTP and WebSocket port: the view is ``http://host:port/``, the stream
        ``ws://host:port/ws``.
    room : tuple of float, optional
        ``[x0, y0, x1, y1]`` drawn as the room; the sensors' reach when omitted.
    max_queue : int
        Frames a slow client may lag behind before it is dropped.
    token_file : Path, optional
        A file holding an access token (its first line). When set, the stream and the
        scene are served only to requests that carry it, as ``?token=...`` in the address
        (what a browser can do) or an ``Authorization: Bearer`` header; the page passes
        its own ``?token=`` on.
    tls_certificate, tls_private_key : Path, optional
        Serve HTTPS and ``wss://`` with this certificate and key (PEM), e.g. the output
        node's own from ``openptrack certs``. Both or neither.
    """

    host: str = "127.0.0.1"
    port: int = Field(8080, ge=0, le=65535)
    room: tuple[float, float, float, float] | None = None
    max_queue: int = Field(32, ge=1, le=10_000)
    token_file: Path | None = None
    tls_certificate: Path | None = None
    tls_private_key: Path | None = None

    @model_validator(mode="after")
    def _tls_pair(self) -> WebConfig:
        if (self.tls_certificate is None) != (self.tls_private_key is None):
            raise ValueError(
                "tls_certificate and tls_private_key go together: give both or neither"
            )
        return self

    def token(self) -> str | None:
        """The access token, read from :attr:`token_file`; ``None`` when there is none.

        Raises
        ------
        ConfigError
            If the file cannot be read or holds no token of at least 16 characters.
        """
        if self.token_file is None:
            return None
        try:
            lines = self.token_file.expanduser().read_text().splitlines()
        except OSError as exc:
            raise ConfigError(
                f"outputs.web.token_file: cannot read {self.token_file}: {exc}"
            ) from None
        token = lines[0].strip() if lines else ""
        if len(token) < MIN_TOKEN_CHARS:
            raise ConfigError(
                f"outputs.web.token_file: {self.token_file} must start with a token of at least "
                f"{MIN_TOKEN_CHARS} characters (e.g. python -c 'import secrets; "
                "print(secrets.token_urlsafe())')"
            )
        return token

    @field_validator("room")
    @classmethod
    def _room_has_area(
        cls, room: tuple[float, float, float, float] | None
    ) -> tuple[float, float, float, float] | None:
        if room is not None and not (room[2] > room[0] and room[3] > room[1]):
            raise ValueError("must be [x0, y0, x1, y1] with x1 > x0 and y1 > y0")
        return room


class ZoneSinkConfig(StrictModel):
    """One destination of zone events: who entered or left a zone, and zone counts.

    The zones are the network's ``zones``. See :mod:`openptrack_py.output.zone_events`
    for the messages.

    Parameters
    ----------
    host : str
        Destination address.
    port : int
        Destination port.
    format : {"json", "osc"}
        One compact JSON object per UDP datagram, or OSC messages.
    prefix : str
        OSC address prefix (``<prefix>/zone/enter``...).
    counts_every_s : float
        How often every zone's count is sent even when nothing changed (it is also
        sent at every change); 0 sends counts only at changes.
    """

    host: str = "127.0.0.1"
    port: int = Field(21235, ge=1, le=65535)
    format: Literal["json", "osc"] = "json"
    prefix: str = Field("/opt", pattern=r"^(/[A-Za-z0-9_\-]+)+$")
    counts_every_s: float = Field(1.0, ge=0.0, le=3600.0)


class OutputConfig(StrictModel):
    """An output node: smoother and sinks for creative apps.

    Parameters
    ----------
    name : str
        Node name (unique per site).
    host : str
        Machine that runs it.
    source : {"smoothed", "raw"}
        ``smoothed``: the moving-average smoother at a fixed rate. ``raw``: every
        tracker step as it arrives (lowest latency).
    smoother : SmootherConfig
        Smoother parameters.
    republish : bool
        Publish the smoothed tracks on ``opt/<site>/tracks/smoothed``.
    udp : list of UdpSinkConfig
        UDP JSON destinations.
    osc : list of OscSinkConfig
        OSC destinations.
    zones : list of ZoneSinkConfig
        Destinations of zone enter/leave events and counts (the network's ``zones``).
    web : WebConfig, optional
        WebSocket stream and web view.
    """

    name: Name = "output"
    host: str = "localhost"
    source: Literal["smoothed", "raw"] = "smoothed"
    smoother: SmootherConfig = Field(default_factory=SmootherConfig)
    republish: bool = True
    udp: list[UdpSinkConfig] = Field(default_factory=list)
    osc: list[OscSinkConfig] = Field(default_factory=list)
    zones: list[ZoneSinkConfig] = Field(default_factory=list)
    web: WebConfig | None = None
