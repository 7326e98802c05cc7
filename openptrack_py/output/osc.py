"""Tracks as OSC bundles (python-osc), for Max, TouchDesigner, Processing and others.

One bundle per frame (time tag "immediately"), holding, under a configurable prefix
(``/opt`` by default):

=================  ============================================================
``/opt/frame``     ``seq sec nsec count max_id`` (int32 each)
``/opt/track``     ``id x y height age confidence`` (int32, then float32), one
                   message per track
``/opt/identity``  ``id stable_id name`` (int32, int32, string; ``name`` empty when
                   the person is not registered), one message per track with a
                   stable identity (the tracker's identity role is on)
``/opt/alive``     the ids of every live track (int32 each; no argument when none)
=================  ============================================================

Max: ``[udpreceive 7000]`` -> ``[route /opt/track /opt/frame /opt/identity /opt/alive]``.
TouchDesigner: an OSC In DAT on port 7000. Processing: oscP5, ``checkAddrPattern``.
OSC floats are 32-bit: 1.7 arrives as 1.70000005.
"""

from __future__ import annotations

import socket

from openptrack_py.config import OscSinkConfig
from openptrack_py.errors import ConfigError
from openptrack_py.messages.track import TrackBatch
from openptrack_py.output.opt_json import sec_nsec
from openptrack_py.output.sinks import _Resolver

try:
    from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
    from pythonosc.osc_message_builder import OscMessageBuilder
except ImportError:  # pragma: no cover - exercised only without the [osc] extra
    OscBundleBuilder = None  # type: ignore[assignment,misc]


def _message(address: str, args: list[tuple[object, str]]) -> object:
    builder = OscMessageBuilder(address)
    for value, kind in args:
        builder.add_arg(value, kind)
    return builder.build()


def build_bundle(frame: TrackBatch, seq: int, prefix: str = "/opt") -> bytes:
    """The OSC bundle of one frame, as a datagram."""
    bundle = OscBundleBuilder(IMMEDIATELY)
    sec, nsec = sec_nsec(frame.stamp)
    bundle.add_content(
        _message(
            f"{prefix}/frame",
            [(seq, "i"), (sec, "i"), (nsec, "i"), (len(frame.tracks), "i"), (frame.max_id, "i")],
        )
    )
    for t in frame.tracks:
        bundle.add_content(
            _message(
                f"{prefix}/track",
                [
                    (t.id, "i"),
                    (t.x, "f"),
                    (t.y, "f"),
                    (t.height, "f"),
                    (t.age, "f"),
                    (t.confidence, "f"),
                ],
            )
        )
    for t in frame.tracks:
        if t.stable_id is not None:
            bundle.add_content(
                _message(
                    f"{prefix}/identity",
                    [(t.id, "i"), (t.stable_id, "i"), (t.identity or "", "s")],
                )
            )
    bundle.add_content(_message(f"{prefix}/alive", [(i, "i") for i in frame.alive_ids]))
    return bundle.build().dgram


class OscSink:
    """Sends each frame as one OSC bundle over UDP.

    Parameters
    ----------
    cfg : OscSinkConfig
        Destination and address prefix.
    name : str
        Name used in counters and logs.

    Raises
    ------
    ConfigError
        If python-osc (the ``[osc]`` extra) is not installed.
    """

    poll_interval_s = None

    def __init__(self, cfg: OscSinkConfig, name: str = "osc") -> None:
        if OscBundleBuilder is None:
            raise ConfigError(
                "outputs.osc: OSC needs python-osc: pip install 'openptrack_py[osc]'"
            )
        self.cfg = cfg
        self.name = name
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.setblocking(False)
        self._resolver = _Resolver(cfg.host, cfg.port)

    def send(self, frame: TrackBatch, now: float) -> None:
        """Send one frame's bundle."""
        address = self._resolver.address()
        try:
            self._sock.sendto(build_bundle(frame, frame.seq, self.cfg.prefix), address)
        except BlockingIOError:
            raise OSError("socket buffer full, bundle dropped") from None

    def poll(self, now: float) -> None:
        """Nothing periodic."""

    def close(self) -> None:
        """Close the socket."""
        self._sock.close()
