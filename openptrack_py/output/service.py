"""The output node's body: tracks in, smoother, every sink, Zenoh republish.

With ``source: smoothed`` a drift-free ticker runs the
:class:`~openptrack_py.output.smoothing.MovingAverageSmoother` at ``rate_hz`` (ticks
that come too late are counted as ``late_ticks``, never bunched up); with
``source: raw`` every tracker message goes out as soon as it arrives. Each frame goes to
every sink's own worker (UDP JSON, OSC, WebSocket, zone events) and, when
``republish`` is on, to ``opt/<site>/tracks/smoothed``. With a web view, the progress
of a live checkerboard session (``opt/<site>/board_progress``) goes to the page too.
"""

from __future__ import annotations

import time
from dataclasses import replace

from openptrack_py.config import NetworkConfig, OutputConfig
from openptrack_py.messages.codec import decode_track_batch, encode_track_batch
from openptrack_py.messages.track import TrackBatch
from openptrack_py.output.osc import OscSink
from openptrack_py.output.sinks import Sink, SinkWorker, UdpJsonSink
from openptrack_py.output.smoothing import MovingAverageSmoother
from openptrack_py.output.web import WebServer, WebSink, calibration_message, scene
from openptrack_py.output.zone_events import ZoneEventSink
from openptrack_py.runtime.node import Node
from openptrack_py.transport.base import Sample


def build_sinks(
    cfg: OutputConfig, network: NetworkConfig, node: Node
) -> tuple[list[SinkWorker], WebServer | None]:
    """One worker per configured sink, and the web server if any.

    Raises
    ------
    ConfigError
        If a sink's optional dependency is missing or a port cannot be opened.
    """
    sinks: list[Sink] = [UdpJsonSink(u, f"udp{i}") for i, u in enumerate(cfg.udp)]
    sinks += [OscSink(o, f"osc{i}") for i, o in enumerate(cfg.osc)]
    sinks += [ZoneEventSink(z, network.zones, f"zones{i}") for i, z in enumerate(cfg.zones)]
    server = None
    if cfg.web is not None:
        server = WebServer(cfg.web, scene(network, cfg.web), node.counters)
        sinks.append(WebSink(server))
    return [SinkWorker(s, node.counters) for s in sinks], server


class OutputService:
    """Runs an output node.

    Parameters
    ----------
    node : Node
        The node (bus, counters, stop flag).
    cfg : OutputConfig
        This output's settings.
    network : NetworkConfig
        The whole network (sensor poses for the web view).
    """

    def __init__(self, node: Node, cfg: OutputConfig, network: NetworkConfig) -> None:
        self.node = node
        self.cfg = cfg
        s = cfg.smoother
        self.smoother = MovingAverageSmoother(
            s.window_size, s.position_lifetime_s, s.track_lifetime_s
        )
        self._inbox = node.subscribe(node.keys.tracks, decode_track_batch, maxsize=1000)
        self.workers, self.web = build_sinks(cfg, network, node)
        self._republish = node.publisher(node.keys.tracks_smoothed) if cfg.republish else None
        self._last_empty = -float("inf")
        self._seq = 0
        self._progress = None
        if self.web is not None:  # a live board session's progress, drawn by the page
            self._progress = node.bus.subscribe(node.keys.board_progress, self._board_progress)

    def _board_progress(self, sample: Sample) -> None:
        try:
            message = calibration_message(sample.payload)
        except ValueError:
            self.node.counters.inc("web.malformed_progress")
            return
        self.web.broadcast(message, keep=True)  # type: ignore[union-attr]

    def dispatch(self, frame: TrackBatch) -> None:
        """Number a frame, hand it to every sink (never blocks) and republish it.

        Frames are numbered here, as produced, so a frame a slow sink drops shows to its
        client as a gap in ``seq``.
        """
        self._seq += 1
        frame = replace(frame, seq=self._seq)
        for worker in self.workers:
            worker.submit(frame)
        if self._republish is not None:
            self._republish.put(encode_track_batch(frame))
        self.node.counters.inc("frames")

    def _smoothed_frame(self, now: float) -> TrackBatch | None:
        for item in self._inbox.drain(timeout=0):
            self.smoother.push(item.message, item.received)
        frame = self.smoother.frame(now)
        s = self.cfg.smoother
        if frame.tracks or s.publish_empty:
            return frame
        if now - self._last_empty >= s.heartbeat_interval_s:  # OpenPTrack's empty heartbeat
            self._last_empty = now
            return TrackBatch(now, frame.seq, "heartbeat", (), frame.alive_ids, frame.max_id)
        return None

    def run(self) -> None:
        """Serve until the node stops."""
        node = self.node
        if self.web is not None:
            node.log.info(
                "web view",
                extra={"fields": {"url": f"http://{self.cfg.web.host}:{self.web.port}/"}},
            )
        node.log.info("output", extra={"fields": {"source": self.cfg.source}})
        try:
            if self.cfg.source == "raw":
                while node.running:
                    for item in self._inbox.drain(timeout=0.1):
                        self.dispatch(item.message)
            else:
                period = 1.0 / self.cfg.smoother.rate_hz
                start = time.monotonic()
                tick = 0
                while node.running:
                    tick += 1
                    due = start + tick * period
                    delay = due - time.monotonic()
                    if delay > 0:
                        if node.wait(delay):
                            break
                    elif delay < -period:  # fell behind: skip missed ticks, do not bunch
                        skipped = int(-delay / period)
                        tick += skipped
                        node.counters.inc("late_ticks", skipped)
                    frame = self._smoothed_frame(time.time())
                    if frame is not None:
                        self.dispatch(frame)
        finally:
            if self._progress is not None:
                self._progress.close()
            for worker in self.workers:
                worker.close()
