"""Zone events for creative apps: someone entered or left a zone, and how many are in each.

A sink of the output node (``outputs[].zones``): with every frame it asks
:class:`~openptrack_py.zones.ZoneTracker` who is in which of the network's ``zones``
(a person briefly unseen keeps their zones for a second) and sends, to one UDP
destination, an event per change and the counts at every change and every
``counts_every_s``. People are keyed by the id a client sees (``stable_id`` when the
tracker gives one, else the track id).

JSON (``format: json``), one compact object per datagram, no trailing NUL::

    {"zone_event":{"seq":12,"stamp":{"sec":1764000000,"nsec":500000000},
                   "zone":"stage","event":"enter","id":4,"name":"Ada","count":2}}
    {"zone_counts":{"seq":13,"stamp":{"sec":1764000000,"nsec":500000000},
                    "zones":{"stage":2,"bar":0}}}

``event`` is ``enter`` or ``leave``, ``count`` the zone's count after it, ``name`` the
roster's name or ``""``. TouchDesigner: a UDP In DAT (one message per row) and a JSON
DAT; Max: ``[udpreceive 21235]`` -> ``[fromsymbol]`` -> ``[dict.deserialize]``.

OSC (``format: osc``), one message per datagram, under ``prefix`` (``/opt``)::

    /opt/zone/enter   zone id name count     (string, int32, string, int32)
    /opt/zone/leave   zone id name count
    /opt/zone/count   zone count             (one message per zone)

Max: ``[udpreceive 21235]`` -> ``[route /opt/zone/enter /opt/zone/leave /opt/zone/count]``.
"""

from __future__ import annotations

import socket
from collections.abc import Sequence

import orjson

from openptrack_py.config import ZoneConfig, ZoneSinkConfig
from openptrack_py.errors import ConfigError
from openptrack_py.messages.track import TrackBatch
from openptrack_py.output.opt_json import sec_nsec
from openptrack_py.output.sinks import _Resolver
from openptrack_py.zones import ZoneTracker

__all__ = ["ZoneEventSink", "encode_zone_counts", "encode_zone_event"]


def encode_zone_event(
    seq: int, stamp: float, zone: str, event: str, person: int, name: str, count: int
) -> bytes:
    """One zone event as a JSON datagram."""
    sec, nsec = sec_nsec(stamp)
    return orjson.dumps(
        {
            "zone_event": {
                "seq": seq, "stamp": {"sec": sec, "nsec": nsec}, "zone": zone,
                "event": event, "id": person, "name": name, "count": count,
            }
        }
    )  # fmt: skip


def encode_zone_counts(seq: int, stamp: float, counts: dict[str, int]) -> bytes:
    """Every zone's count as a JSON datagram."""
    sec, nsec = sec_nsec(stamp)
    return orjson.dumps(
        {"zone_counts": {"seq": seq, "stamp": {"sec": sec, "nsec": nsec}, "zones": counts}}
    )


def _osc(address: str, args: list[tuple[object, str]]) -> bytes:
    from pythonosc.osc_message_builder import OscMessageBuilder

    builder = OscMessageBuilder(address)
    for value, kind in args:
        builder.add_arg(value, kind)
    return builder.build().dgram


class ZoneEventSink:
    """Sends zone events and counts to one destination.

    Parameters
    ----------
    cfg : ZoneSinkConfig
        Destination and format.
    zones : sequence of ZoneConfig
        The network's zones.
    name : str
        Name used in counters and logs.

    Raises
    ------
    ConfigError
        If the network has no zones, or OSC is asked without python-osc.
    """

    def __init__(
        self, cfg: ZoneSinkConfig, zones: Sequence[ZoneConfig], name: str = "zones"
    ) -> None:
        if not zones:
            raise ConfigError(f"outputs.zones ({name}): the network file has no 'zones'")
        if cfg.format == "osc":
            try:
                import pythonosc  # noqa: F401
            except ImportError:
                raise ConfigError(
                    f"outputs.zones ({name}): format osc needs python-osc (the [osc] extra)"
                ) from None
        self.cfg = cfg
        self.name = name
        self.poll_interval_s = cfg.counts_every_s or None
        self.tracker = ZoneTracker(zones)
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.setblocking(False)
        self._resolver = _Resolver(cfg.host, cfg.port)
        self._seq = 0
        self._names: dict[int, str] = {}
        self._last_stamp = 0.0
        self._next_counts = 0.0

    def _send(self, data: bytes) -> None:
        try:
            self._sock.sendto(data, self._resolver.address())
        except BlockingIOError:
            raise OSError("socket buffer full, datagram dropped") from None

    def _event(self, stamp: float, zone: str, event: str, person: int, count: int) -> None:
        self._seq += 1
        name = self._names.get(person, "")
        if self.cfg.format == "json":
            data = encode_zone_event(self._seq, stamp, zone, event, person, name, count)
        else:
            args = [(zone, "s"), (person, "i"), (name, "s"), (count, "i")]
            data = _osc(f"{self.cfg.prefix}/zone/{event}", args)
        self._send(data)

    def _counts(self, stamp: float, counts: dict[str, int] | None = None) -> None:
        counts = self.tracker.counts() if counts is None else counts
        self._seq += 1
        if self.cfg.format == "json":
            self._send(encode_zone_counts(self._seq, stamp, counts))
        else:
            for zone, count in counts.items():
                self._send(_osc(f"{self.cfg.prefix}/zone/count", [(zone, "s"), (count, "i")]))

    def send(self, frame: TrackBatch, now: float) -> None:
        """Take one tracks frame: an event per change, then the counts if any changed."""
        positions = {}
        for t in frame.tracks:
            key = t.client_id
            positions[key] = (t.x, t.y)
            if t.identity:
                self._names[key] = t.identity
        self._last_stamp = frame.stamp
        entered, left = self.tracker.update(frame.stamp, positions)
        counts = self.tracker.counts()
        for person, zone in left:
            self._event(frame.stamp, zone, "leave", person, counts[zone])
        for person, zone in entered:
            self._event(frame.stamp, zone, "enter", person, counts[zone])
        if entered or left:
            self._counts(frame.stamp, counts)
            self._next_counts = now + self.cfg.counts_every_s
        present = set(positions) | set(self.tracker.current)
        self._names = {k: v for k, v in self._names.items() if k in present}

    def poll(self, now: float) -> None:
        """Send the counts when due (also while nothing changes)."""
        if self.cfg.counts_every_s and now >= self._next_counts:
            self._next_counts = now + self.cfg.counts_every_s
            self._counts(self._last_stamp or now)

    def close(self) -> None:
        """Close the socket."""
        self._sock.close()
