"""``openptrack launch``: start this host's nodes of a network file and supervise them.

The command line only; planning and supervising the node processes is
:mod:`openptrack_py.launch`.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING

from openptrack_py.cli.common import EXIT_CONFIG, add_log_options
from openptrack_py.config import NetworkConfig, load_network
from openptrack_py.errors import ConfigError
from openptrack_py.runtime.args import resolve_config_path

if TYPE_CHECKING:
    import threading

    from openptrack_py.cli.common import Subparsers
    from openptrack_py.launch import Supervisor
    from openptrack_py.runtime.status import StatusBoard
    from openptrack_py.transport.zenoh_bus import ZenohBus

RGBD_START_DELAY_S = 3.0
"""With ``sim.sensor_model: rgbd``, the shared scenario start this far after launch."""


def add_parser(subparsers: Subparsers) -> None:
    """Register ``launch``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
        "launch",
        help="start this host's nodes of a network file and supervise them",
        description="Start the nodes a network file assigns to this host, prefix their logs, "
        "restart crashed ones, stop all on Ctrl-C.",
    )
    p.add_argument("network", help="network file or preset name (e.g. demo)")
    p.add_argument("--host", help="host name to launch for (default: this machine)")
    p.add_argument("--duration", type=float, help="stop everything after S seconds")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument(
        "--status-interval", type=float, default=5.0, help="seconds between status lines (0: off)"
    )
    p.add_argument(
        "--table",
        action="store_true",
        help="show a live table of the tracks and node rates (node logs: warnings only)",
    )
    add_log_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Start the nodes, supervise them until they end or a signal asks; return the status."""
    from openptrack_py.config.network import LAUNCHER
    from openptrack_py.launch import Supervisor, host_matches, plan_nodes, this_host
    from openptrack_py.runtime.status import StatusBoard
    from openptrack_py.security.policy import session_settings
    from openptrack_py.transport.zenoh_bus import ZenohBus

    path = resolve_config_path(args.network)
    assert path is not None
    cfg = load_network(path, args.overrides)
    host = args.host or this_host()
    specs = plan_nodes(cfg, host, path.resolve(), _node_flags(args, cfg))
    if not specs:
        print(f"openptrack launch: no node of {path} runs on host {host!r}", file=sys.stderr)
        return EXIT_CONFIG
    hub = None
    if cfg.zenoh.hub is not None and host_matches(cfg.zenoh.hub_host, host):
        try:
            hub = ZenohBus(cfg.zenoh, as_hub=True, settings=session_settings(cfg, LAUNCHER))
        except ConfigError as exc:
            print(
                f"openptrack launch: cannot open the hub {cfg.zenoh.hub}: {exc}", file=sys.stderr
            )
            return EXIT_CONFIG
    supervisor = Supervisor(specs)
    names = ", ".join(s.name for s in specs)
    supervisor.say("launch", f"site {cfg.site!r} on host {host!r}: starting {names}")
    if hub is not None:
        supervisor.say("launch", f"hub listening on {cfg.zenoh.hub}")

    supervisor.install_signal_handlers()
    board = StatusBoard(hub, cfg.site) if hub is not None else None
    stop = None
    if hub is not None and board is not None and (args.status_interval > 0 or args.table):
        stop = _start_reporter(args, supervisor, hub, board, cfg.site)
    try:
        return supervisor.run(args.duration)
    finally:
        if stop is not None:
            stop.set()
        if board is not None:
            board.close()
        if hub is not None:
            hub.close()


def _node_flags(args: argparse.Namespace, cfg: NetworkConfig) -> list[str]:
    """The flags every node of this launch receives after ``-c NETWORK``."""
    passthrough = [a for o in args.overrides for a in ("--set", o)]
    # With the live table, node logs would scroll it away: only warnings get through.
    level = "warning" if args.table and args.log_level == "info" else args.log_level
    passthrough += ["--log-level", level, "--log-format", args.log_format]
    if cfg.sim is not None and cfg.sim.sensor_model == "rgbd" and cfg.sim.start_time is None:
        # Rendering detectors and the simulator must play the same world at the same time.
        passthrough += ["--set", f"sim.start_time={time.time() + RGBD_START_DELAY_S:.3f}"]
    return passthrough


def _start_reporter(
    args: argparse.Namespace,
    supervisor: Supervisor,
    hub: ZenohBus,
    board: StatusBoard,
    site: str,
) -> threading.Event:
    """Print status lines (or the live table) from a daemon thread until the event is set."""
    import threading

    from openptrack_py.runtime.table import TrackView, render

    stop = threading.Event()
    view = TrackView(hub, site) if args.table else None
    redraw = sys.stdout.isatty()
    interval = 1.0 if args.table else args.status_interval

    def report() -> None:
        while not stop.wait(interval):
            if view is None:
                supervisor.say("status", board.summary_line())
            elif redraw:  # a terminal: repaint in place, like top
                supervisor.say_raw("\x1b[H\x1b[J" + render(view, board) + "\n")
            else:
                for line in render(view, board).splitlines():
                    supervisor.say("table", line)

    threading.Thread(target=report, daemon=True).start()
    return stop
