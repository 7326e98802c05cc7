"""Outputs for creative apps: smoother, OpenPTrack UDP JSON, OSC, WebSocket and web view."""

from openptrack_py.output.opt_json import encode_opt_heartbeat, encode_tracks, parse_datagram
from openptrack_py.output.sinks import Sink, SinkWorker, UdpJsonSink
from openptrack_py.output.smoothing import MovingAverageSmoother

__all__ = [
    "MovingAverageSmoother",
    "Sink",
    "SinkWorker",
    "UdpJsonSink",
    "encode_opt_heartbeat",
    "encode_tracks",
    "parse_datagram",
]
