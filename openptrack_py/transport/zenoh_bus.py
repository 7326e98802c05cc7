"""The real bus: one Zenoh session.

Peer mode by default with explicit endpoints and multicast scouting off, so nodes meet
only where the network file says. Reliable publishers use ``CongestionControl.BLOCK``
(nothing is dropped when a subscriber is slow); unreliable ones use ``DROP`` with
``express`` for latest-only data.
"""

from __future__ import annotations

import contextlib
import errno
import json
import logging
import os
import socket
import threading
import time
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import zenoh

from openptrack_py.config import ZenohConfig
from openptrack_py.config.base import NETWORK_PROTOCOLS, split_host_port
from openptrack_py.errors import ConfigError
from openptrack_py.transport.base import (
    LivelinessHandler,
    QueryHandler,
    Sample,
    SampleHandler,
)
from openptrack_py.transport.keys import validate_key

log = logging.getLogger(__name__)

_zenoh_log_once = threading.Lock()
_zenoh_log_done = False


def _init_zenoh_logging() -> None:
    """Zenoh's logger at ``RUST_LOG`` (``error`` if unset), without colour codes in files.

    Zenoh writes to descriptor 1; when that is not a terminal (a pipe, a log file, the
    launcher's prefixing), ``NO_COLOR`` (honoured by its logger) keeps ANSI escapes out.
    """
    global _zenoh_log_done
    with _zenoh_log_once:
        if not _zenoh_log_done:
            if not os.isatty(1):
                os.environ.setdefault("NO_COLOR", "1")
            zenoh.init_log_from_env_or("error")
            _zenoh_log_done = True


def build_zenoh_config(
    cfg: ZenohConfig,
    *,
    listen: Sequence[str] | None = None,
    connect: Sequence[str] | None = None,
    as_hub: bool = False,
    settings: Mapping[str, Any] | None = None,
) -> zenoh.Config:
    """Translate a :class:`~openptrack_py.config.ZenohConfig` into a ``zenoh.Config``.

    Parameters
    ----------
    cfg : ZenohConfig
        The network's Zenoh section.
    listen, connect : sequence of str, optional
        Replace ``cfg.listen`` / ``cfg.connect`` (command-line ``-l`` / ``-e``).
    as_hub : bool
        Listen on ``cfg.hub`` instead of connecting to it (the launcher on the hub host).
    settings : mapping, optional
        Further Zenoh configuration entries, path -> value (e.g. ``transport/link/tls``
        and ``access_control`` from :func:`openptrack_py.security.policy.session_settings`).

    Raises
    ------
    ConfigError
        If the Zenoh JSON5 file cannot be read or a value is refused by Zenoh.
    """
    if cfg.config_file is not None:
        try:
            zcfg = zenoh.Config.from_file(str(cfg.config_file))
        except Exception as exc:
            raise ConfigError(f"zenoh.config_file: cannot load {cfg.config_file}: {exc}") from None
    else:
        zcfg = zenoh.Config()
    listen_eps = list(cfg.listen if listen is None else listen)
    connect_eps = list(cfg.connect if connect is None else connect)
    if cfg.hub is not None:
        if as_hub:
            listen_eps = [cfg.hub, *[e for e in listen_eps if e != cfg.hub]]
        elif cfg.hub not in connect_eps and (cfg.mode != "peer" or cfg.hub not in listen_eps):
            connect_eps.append(cfg.hub)  # (a peer listening on the hub is the hub)
    entries = {
        "mode": json.dumps(cfg.mode),
        "listen/endpoints": json.dumps(listen_eps if cfg.mode == "peer" or as_hub else []),
        "connect/endpoints": json.dumps(connect_eps),
        "scouting/multicast/enabled": json.dumps(cfg.multicast_scouting),
        "transport/shared_memory/enabled": json.dumps(cfg.shared_memory),
    }
    entries.update({key: json.dumps(value) for key, value in (settings or {}).items()})
    for key, value in entries.items():
        try:
            zcfg.insert_json5(key, value)
        except Exception as exc:
            raise ConfigError(f"zenoh: Zenoh refused {key}={value}: {exc}") from None
    return zcfg


def _safe(handler: SampleHandler, what: str) -> SampleHandler:
    def call(sample: Sample) -> None:
        try:
            handler(sample)
        except Exception:  # a handler bug must not kill Zenoh's delivery thread
            log.exception("handler for %s raised", what)

    return call


class _ZenohPublisher:
    def __init__(self, session: zenoh.Session, key: str, reliable: bool) -> None:
        self.key = key
        self._pub = session.declare_publisher(
            key,
            congestion_control=(
                zenoh.CongestionControl.BLOCK if reliable else zenoh.CongestionControl.DROP
            ),
            express=not reliable,
        )
        self._closed = False

    def put(self, payload: bytes) -> None:
        self._pub.put(payload)

    def has_subscribers(self) -> bool:
        # The property returns a MatchingStatus object (always truthy), not a bool.
        return bool(self._pub.matching_status.matching)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            with contextlib.suppress(Exception):  # the session may be closed already
                self._pub.undeclare()


class _Declared:
    """Wraps a Zenoh entity so that closing it twice, or after the session, is harmless."""

    def __init__(self, entity: object) -> None:
        self._entity = entity

    def close(self) -> None:
        entity, self._entity = self._entity, None
        if entity is not None:
            with contextlib.suppress(Exception):
                entity.undeclare()  # type: ignore[attr-defined]


def check_resolvable(
    cfg: ZenohConfig,
    *,
    listen: Sequence[str] | None = None,
    connect: Sequence[str] | None = None,
) -> None:
    """Check that every host name of the endpoints resolves on this machine.

    Raises
    ------
    ConfigError
        Naming the key, the endpoint and the resolver's answer (instead of Zenoh's
        error from deep inside its runtime).
    """
    for key, endpoint in cfg.named_endpoints(listen, connect):
        protocol, _, address = endpoint.partition("/")
        if protocol not in NETWORK_PROTOCOLS:
            continue
        host, port = split_host_port(address.split("#", 1)[0])
        try:
            socket.getaddrinfo(host.strip("[]"), port)
        except (OSError, UnicodeError) as exc:
            raise ConfigError(f"{key}: cannot resolve the host of {endpoint!r} ({exc})") from None


def busy_listen_endpoint(
    cfg: ZenohConfig,
    *,
    listen: Sequence[str] | None = None,
    as_hub: bool = False,
) -> tuple[str, str] | None:
    """The first TCP endpoint this session would listen on that another process holds.

    Asked after Zenoh refused to open a session, to say which endpoint is taken (Zenoh
    says only ``ZError``). Returns ``(key, endpoint)`` or ``None``.
    """
    for key, endpoint in cfg.named_endpoints(listen, None):
        peer_listens = key.startswith("zenoh.listen") and cfg.mode == "peer"
        listens = peer_listens or (key == "zenoh.hub" and as_hub)
        protocol, _, address = endpoint.partition("/")
        if not listens or protocol != "tcp":
            continue
        host, port = split_host_port(address.split("#", 1)[0])
        try:
            family = socket.AF_INET6 if ":" in host.strip("[]") else socket.AF_INET
            with socket.socket(family, socket.SOCK_STREAM) as probe:
                probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # TIME_WAIT is free
                probe.bind((host.strip("[]"), int(port)))
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                return key, endpoint
    return None


def _first_line(exc: BaseException) -> str:
    """An exception's message without the source locations a Rust error may carry."""
    lines = [ln for ln in str(exc).splitlines() if ln.strip() and ".rs:" not in ln]
    return lines[0].strip() if lines else type(exc).__name__


class ZenohBus:
    """A :class:`~openptrack_py.transport.base.Bus` over one Zenoh session.

    Parameters
    ----------
    cfg : ZenohConfig, optional
        Endpoints and mode; defaults to peer mode connecting to ``tcp/127.0.0.1:7447``.
    listen, connect : sequence of str, optional
        Override the configured endpoints.
    as_hub : bool
        Listen on the hub endpoint instead of connecting to it.
    settle_s : float
        After opening, wait until the set of linked peers has not changed for this long
        (at most ``10 * settle_s``). Queries and liveliness requests sent while a peer
        mesh is still forming can go unanswered for seconds (measured: 2 of 3 fresh
        processes got no reply within 3 s when querying at once, none lost after 50 ms).
    settings : mapping, optional
        Further Zenoh configuration entries (see :func:`build_zenoh_config`).
    """

    def __init__(
        self,
        cfg: ZenohConfig | None = None,
        *,
        listen: Sequence[str] | None = None,
        connect: Sequence[str] | None = None,
        as_hub: bool = False,
        settle_s: float = 0.1,
        settings: Mapping[str, Any] | None = None,
    ) -> None:
        _init_zenoh_logging()
        self.config = cfg if cfg is not None else ZenohConfig()
        zcfg = build_zenoh_config(
            self.config, listen=listen, connect=connect, as_hub=as_hub, settings=settings
        )
        check_resolvable(self.config, listen=listen, connect=connect)
        try:
            self.session = zenoh.open(zcfg)
        except Exception as exc:
            busy = busy_listen_endpoint(self.config, listen=listen, as_hub=as_hub)
            if busy is not None:
                raise ConfigError(
                    f"{busy[0]}: cannot listen on {busy[1]}: the address is already in use "
                    "(another node or launcher listens there; pick another port)"
                ) from None
            raise ConfigError(f"zenoh: cannot open a session: {_first_line(exc)}") from None
        self._closed = False
        self._lock = threading.Lock()
        if settle_s > 0 and not as_hub:
            self._settle(settle_s)

    def _links(self) -> frozenset[str]:
        info = self.session.info
        return frozenset(str(z) for z in (*info.peers_zid(), *info.routers_zid()))

    def _settle(self, quiet_s: float) -> None:
        deadline = time.monotonic() + 10 * quiet_s
        links = self._links()
        stable_since = time.monotonic()
        while time.monotonic() < deadline:
            time.sleep(quiet_s / 10)
            current = self._links()
            if current != links or not current:
                links, stable_since = current, time.monotonic()
            elif time.monotonic() - stable_since >= quiet_s:
                return

    def __enter__(self) -> ZenohBus:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called."""
        return self._closed

    def publisher(self, key: str, *, reliable: bool = True) -> _ZenohPublisher:
        """Declare a publisher (BLOCK congestion control when ``reliable``)."""
        return _ZenohPublisher(self.session, validate_key(key), reliable)

    def put(self, key: str, payload: bytes, *, reliable: bool = True) -> None:
        """Publish once."""
        self.session.put(
            validate_key(key),
            payload,
            congestion_control=(
                zenoh.CongestionControl.BLOCK if reliable else zenoh.CongestionControl.DROP
            ),
        )

    def subscribe(self, keyexpr: str, handler: SampleHandler) -> _Declared:
        """Call ``handler`` on Zenoh's thread for every matching sample."""
        safe = _safe(handler, keyexpr)

        def on_sample(sample: zenoh.Sample) -> None:
            if sample.kind == zenoh.SampleKind.PUT:
                safe(Sample(str(sample.key_expr), sample.payload.to_bytes()))

        return _Declared(
            self.session.declare_subscriber(validate_key(keyexpr, allow_wildcards=True), on_sample)
        )

    def declare_token(self, key: str) -> _Declared:
        """Announce a liveliness token."""
        return _Declared(self.session.liveliness().declare_token(validate_key(key)))

    def alive(self, keyexpr: str, timeout_s: float = 0.5) -> list[str]:
        """Keys of the liveliness tokens matching ``keyexpr``, collected for ``timeout_s``.

        Uses a liveliness subscriber with history rather than a liveliness query: in peer
        mode a query sent just after a token was declared elsewhere could go unanswered
        for seconds (3 of 3 fresh processes), the subscriber's history never did (0 of 6).
        """
        present: set[str] = set()
        lock = threading.Lock()

        def on_change(key: str, alive: bool) -> None:
            with lock:
                if alive:
                    present.add(key)
                else:
                    present.discard(key)

        sub = self.subscribe_liveliness(keyexpr, on_change)
        try:
            time.sleep(timeout_s)
        finally:
            sub.close()
        with lock:
            return sorted(present)

    def subscribe_liveliness(self, keyexpr: str, handler: LivelinessHandler) -> _Declared:
        """Report tokens appearing (``True``) and disappearing (``False``)."""

        def on_sample(sample: zenoh.Sample) -> None:
            try:
                handler(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT)
            except Exception:
                log.exception("liveliness handler for %s raised", keyexpr)

        return _Declared(
            self.session.liveliness().declare_subscriber(
                validate_key(keyexpr, allow_wildcards=True), on_sample, history=True
            )
        )

    def serve(self, keyexpr: str, handler: QueryHandler) -> _Declared:
        """Answer queries matching ``keyexpr``."""
        expr = validate_key(keyexpr, allow_wildcards=True)

        def on_query(query: zenoh.Query) -> None:
            asked = str(query.key_expr)
            payload = query.payload.to_bytes() if query.payload is not None else None
            try:
                reply = handler(asked, payload)
            except Exception:
                log.exception("query handler for %s raised", expr)
                return
            if reply is not None:
                query.reply(asked if "*" not in asked else expr, reply)

        return _Declared(self.session.declare_queryable(expr, on_query))

    def query(
        self, selector: str, payload: bytes | None = None, timeout_s: float = 1.0
    ) -> list[Sample]:
        """Ask every matching queryable; wait at most ``timeout_s``."""
        replies = self.session.get(
            validate_key(selector, allow_wildcards=True), payload=payload, timeout=timeout_s
        )
        return [
            Sample(str(r.ok.key_expr), r.ok.payload.to_bytes())
            for r in replies
            if r.ok is not None
        ]

    def peers(self) -> list[str]:
        """Zenoh ids of the peers this session is linked to."""
        return [str(z) for z in self.session.info.peers_zid()]

    def close(self) -> None:
        """Close the session; idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        try:
            self.session.close()
        except Exception:
            log.debug("zenoh session close raised", exc_info=True)


def endpoints_from_flags(values: Iterable[str] | None) -> list[str] | None:
    """Normalise repeated/comma-separated ``-e``/``-l`` flags; ``None`` when none given."""
    if not values:
        return None
    out: list[str] = []
    for value in values:
        out.extend(v.strip() for v in value.split(",") if v.strip())
    return out
