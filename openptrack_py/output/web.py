"""The WebSocket stream and the live web view, on one port.

``http://host:port/`` is a self-contained page (no build step, nothing from a CDN) that
draws the room from above: tracks with ids and fading trails, sensors with their fields
of view, a frame counter and the frame rate. ``ws://host:port/ws`` streams JSON text
messages, which any browser sketch (p5.js...) can read:

* on connection, once: ``{"type": "scene", "site": ..., "room": [x0, y0, x1, y1],
  "sensors": [{"id", "type", "x", "y", "z", "yaw_deg", "pitch_deg", "hfov_deg",
  "range_m"}]}``;
* every frame: ``{"type": "tracks", "seq", "stamp", "tracks": [{"id", "x", "y", "z",
  "height", "vx", "vy", "age", "confidence", "visibility", "confirmed"}], "alive_ids",
  "max_id"}``; tracks with a stable identity also carry ``stable_id`` and ``identity``
  (the same track objects as on ``opt/<site>/tracks``);
* during a live checkerboard session (``openptrack calibrate checkerboard --live``), its
  progress: ``{"type": "calibration", "stamp", "seeing": [sensor ids], "views":
  {sensor: n}, "pair_views": {"a|b": n}, "coverage": {sensor: 0..1}, "connected"}``
  (the latest also to each client that connects later). The page shows it as a panel.

Each client has a queue of ``max_queue`` frames; a client that falls that far behind is
disconnected (close code 1013, "try again later") rather than buffered without bound,
and counted as ``web.slow_clients``.

With ``token_file`` set, the data (the stream and ``/scene.json``) is served only to
requests that carry the token, as ``?token=...`` or ``Authorization: Bearer ...``; the
page (the same for everyone) passes its own ``?token=`` on to the stream. Others get
401 and are counted as ``web.refused``. With ``tls_certificate`` and ``tls_private_key``
the server speaks HTTPS and ``wss://``.
"""

from __future__ import annotations

import asyncio
import hmac
import importlib.resources
import logging
import ssl
import threading
from typing import Any
from urllib.parse import parse_qs, urlsplit

import orjson

from openptrack_py.config import NetworkConfig, WebConfig
from openptrack_py.errors import ConfigError
from openptrack_py.messages.codec import track_dict
from openptrack_py.messages.track import TrackBatch
from openptrack_py.runtime.counters import Counters
from openptrack_py.sensor_types import SENSOR_TYPES

log = logging.getLogger(__name__)
# one line per HTTP request and connection is too much for a node's log
logging.getLogger("websockets").setLevel(logging.WARNING)

try:
    from websockets.asyncio.server import ServerConnection, serve
    from websockets.exceptions import ConnectionClosed
except ImportError:  # pragma: no cover - exercised only without the [web] extra
    serve = None  # type: ignore[assignment]

PRIVATE_PATHS = ("/ws", "/scene.json")
"""What needs the token: the data. The page and its script are the same for everyone."""
_CONTENT_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8"}


def scene(network: NetworkConfig, cfg: WebConfig) -> dict[str, Any]:
    """What the view draws besides tracks: room outline and sensors."""
    sensors = []
    for s in network.sensors:
        if s.pose is None:
            continue
        kind = SENSOR_TYPES[s.type]
        sensors.append(
            {
                "id": s.id,
                "type": s.type,
                "x": s.pose.x,
                "y": s.pose.y,
                "z": s.pose.z,
                "yaw_deg": s.pose.yaw_deg,
                "pitch_deg": s.pose.pitch_deg,
                "hfov_deg": kind.hfov_deg,
                "range_m": kind.reliable_range_m,
            }
        )
    room = list(cfg.room) if cfg.room is not None else _reach(sensors)
    return {"type": "scene", "site": network.site, "room": room, "sensors": sensors}


def _reach(sensors: list[dict[str, Any]]) -> list[float]:
    if not sensors:
        return [-5.0, -5.0, 5.0, 5.0]
    xs = [s["x"] for s in sensors]
    ys = [s["y"] for s in sensors]
    return [min(xs) - 1.0, min(ys) - 1.0, max(xs) + 1.0, max(ys) + 1.0]


def frame_message(frame: TrackBatch) -> bytes:
    """The JSON text message of one frame."""
    return orjson.dumps(
        {
            "type": "tracks",
            "seq": frame.seq,
            "stamp": frame.stamp,
            "tracks": [track_dict(t) for t in frame.tracks],
            "alive_ids": list(frame.alive_ids),
            "max_id": frame.max_id,
        }
    )


MAX_PROGRESS_BYTES = 1 << 16
"""A board session's progress is a few hundred bytes; larger is refused."""


def calibration_message(payload: bytes) -> bytes:
    """The page's message for a board session's progress (``opt/<site>/board_progress``).

    Only the known fields are passed on, each checked.

    Raises
    ------
    ValueError
        If the payload is not such a progress report.
    """
    if len(payload) > MAX_PROGRESS_BYTES:
        raise ValueError("board progress: too large")
    data = orjson.loads(payload)
    if not isinstance(data, dict):
        raise ValueError("board progress: not an object")
    stamp = data.get("stamp")
    if stamp is not None and (
        not isinstance(stamp, (int, float)) or isinstance(stamp, bool) or not 0 <= stamp <= 1e11
    ):
        raise ValueError("board progress: stamp")
    seeing = data.get("seeing", [])
    connected = data.get("connected")
    if not isinstance(seeing, list) or not all(isinstance(s, str) for s in seeing):
        raise ValueError("board progress: seeing")
    if not isinstance(connected, bool):
        raise ValueError("board progress: connected")
    out: dict[str, Any] = {"type": "calibration", "stamp": stamp, "seeing": seeing,
                           "connected": connected}  # fmt: skip
    for name, kind, top in (("views", int, 1e9), ("pair_views", int, 1e9), ("coverage", float, 1)):
        table = data.get(name, {})
        if not isinstance(table, dict) or not all(
            isinstance(k, str)
            and isinstance(v, (int, float))
            and not isinstance(v, bool)
            and 0 <= v <= top  # also refuses NaN
            for k, v in table.items()
        ):
            raise ValueError(f"board progress: {name}")
        out[name] = {k: kind(v) for k, v in table.items()}
    return orjson.dumps(out)


def _static(name: str) -> bytes:
    return importlib.resources.files("openptrack_py.output").joinpath("web", name).read_bytes()


def _server_tls(cfg: WebConfig) -> ssl.SSLContext | None:
    """The server's TLS context, or ``None`` without a certificate.

    Raises
    ------
    ConfigError
        If the certificate or key cannot be loaded.
    """
    if cfg.tls_certificate is None or cfg.tls_private_key is None:
        return None
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    context.minimum_version = ssl.TLSVersion.TLSv1_2
    try:
        context.load_cert_chain(cfg.tls_certificate.expanduser(), cfg.tls_private_key.expanduser())
    except (OSError, ssl.SSLError) as exc:
        raise ConfigError(
            f"outputs.web.tls_certificate: cannot load {cfg.tls_certificate} with "
            f"{cfg.tls_private_key}: {exc}"
        ) from None
    return context


class WebServer:
    """Serves the page and the stream from its own thread and event loop.

    Parameters
    ----------
    cfg : WebConfig
        Address, port (0: any free port, see :attr:`port`) and client queue size.
    scene_message : dict
        Sent to each client on connection.
    counters : Counters
        Where ``web.clients``, ``web.slow_clients`` are counted.

    Raises
    ------
    ConfigError
        If the ``websockets`` package (the ``[web]`` extra) is missing or the port is
        taken.
    """

    def __init__(self, cfg: WebConfig, scene_message: dict[str, Any], counters: Counters) -> None:
        if serve is None:
            raise ConfigError("outputs.web: the web view needs pip install 'openptrack_py[web]'")
        self.cfg = cfg
        self.counters = counters
        self._token = cfg.token()
        self._ssl = _server_tls(cfg)
        if self._token is not None and self._ssl is None:
            log.warning(
                "outputs.web: a token without tls_certificate crosses the network in clear "
                "text; anyone on the path can read and reuse it"
            )
        self._scene = orjson.dumps(scene_message)
        self._clients: dict[ServerConnection, asyncio.Queue[str]] = {}
        self._closing: set[asyncio.Task[None]] = set()
        self._calibration: str | None = None  # the latest board-session progress
        self._files = {f"/{n}": _static(n) for n in ("index.html", "view.js")}
        self._files["/"] = self._files["/index.html"]
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._stop: asyncio.Future[None] | None = None
        self._error: BaseException | None = None
        self.port = cfg.port
        self._thread = threading.Thread(target=self._run, name="web", daemon=True)
        self._thread.start()
        self._ready.wait(10.0)
        if self._error is not None:
            raise ConfigError(
                f"outputs.web: cannot listen on {cfg.host}:{cfg.port}: {self._error}"
            ) from None

    # ------------------------------------------------------------- event loop side

    def _authorised(self, request: Any) -> bool:
        if self._token is None:
            return True
        offered = parse_qs(urlsplit(request.path).query).get("token", [""])[0]
        header = request.headers.get("Authorization", "")
        if header.startswith("Bearer "):
            offered = header[len("Bearer ") :].strip()
        return hmac.compare_digest(offered.encode(), self._token.encode())

    def _http(self, connection: ServerConnection, request: Any) -> Any:
        path = request.path.split("?", 1)[0]
        if path in PRIVATE_PATHS and not self._authorised(request):
            self.counters.inc("web.refused")
            return connection.respond(401, "a valid token is needed: ?token=...\n")
        if path == "/ws":
            return None  # go on with the WebSocket handshake
        if path == "/scene.json":
            body, kind = self._scene, "application/json"
        elif path in self._files:
            body = self._files[path]
            kind = _CONTENT_TYPES[".js" if path.endswith(".js") else ".html"]
        else:
            return connection.respond(404, "not found\n")
        response = connection.respond(200, "")
        response.body = body
        del response.headers["Content-Type"]
        del response.headers["Content-Length"]
        response.headers["Content-Type"] = kind
        response.headers["Content-Length"] = str(len(body))
        response.headers["Cache-Control"] = "no-store"
        return response

    async def _client(self, ws: ServerConnection) -> None:
        queue: asyncio.Queue[str] = asyncio.Queue(self.cfg.max_queue)
        self._clients[ws] = queue
        self.counters.inc("web.clients")
        closed = asyncio.ensure_future(ws.wait_closed())  # notice a client that left
        try:
            await ws.send(self._scene.decode())
            if self._calibration is not None:
                await ws.send(self._calibration)
            while True:
                getter = asyncio.ensure_future(queue.get())
                await asyncio.wait({getter, closed}, return_when=asyncio.FIRST_COMPLETED)
                if not getter.done():
                    getter.cancel()
                    break
                await ws.send(getter.result())
        except ConnectionClosed:
            pass
        finally:
            closed.cancel()
            self._clients.pop(ws, None)

    def _broadcast(self, message: bytes, keep: bool = False) -> None:
        text = message.decode()  # once for every client: sent as a text frame
        if keep:
            self._calibration = text
        for ws, queue in list(self._clients.items()):
            if queue.full():
                self._clients.pop(ws, None)
                self.counters.inc("web.slow_clients")
                task = self._loop.create_task(ws.close(1013, "too slow: dropped"))
                self._closing.add(task)  # keep a reference until it is done
                task.add_done_callback(self._closing.discard)
                continue
            queue.put_nowait(text)

    async def _main(self) -> None:
        try:
            server = await serve(
                self._client,
                self.cfg.host,
                self.cfg.port,
                process_request=self._http,
                ssl=self._ssl,
            )
        except OSError as exc:
            self._error = exc
            self._ready.set()
            return
        self.port = server.sockets[0].getsockname()[1]
        self._stop = self._loop.create_future()
        self._ready.set()
        async with server:
            await self._stop

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)
        self._loop.run_until_complete(self._main())

    # ------------------------------------------------------------------ any thread

    def broadcast(self, message: bytes, *, keep: bool = False) -> None:
        """Queue a message for every client (thread-safe, never blocks).

        With ``keep``, the message is also sent to every client that connects later
        (until the next kept one).
        """
        self._loop.call_soon_threadsafe(self._broadcast, message, keep)

    @property
    def clients(self) -> int:
        """Connected clients."""
        return len(self._clients)

    def close(self) -> None:
        """Disconnect everyone and stop serving."""
        if self._stop is not None and not self._loop.is_closed():
            self._loop.call_soon_threadsafe(self._stop.set_result, None)
        self._thread.join(5.0)


class WebSink:
    """Streams frames to the web server's clients.

    Parameters
    ----------
    server : WebServer
        The server.
    name : str
        Name used in counters and logs.
    """

    poll_interval_s = None

    def __init__(self, server: WebServer, name: str = "web") -> None:
        self.server = server
        self.name = name

    def send(self, frame: TrackBatch, now: float) -> None:
        """Queue one frame for every client."""
        self.server.broadcast(frame_message(frame))

    def poll(self, now: float) -> None:
        """Nothing periodic."""

    def close(self) -> None:
        """Stop the server."""
        self.server.close()
