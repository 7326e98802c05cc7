"""The common ``main`` of node processes: flags, config, bus, node, clean exit codes."""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Callable, Sequence

from openptrack_py.config import NetworkConfig
from openptrack_py.config.network import detector_node_name
from openptrack_py.errors import ConfigError
from openptrack_py.runtime.args import add_common_arguments, bus_from_args, network_from_args
from openptrack_py.runtime.logs import configure_logging
from openptrack_py.runtime.node import Node

EXIT_OK = 0
EXIT_CONFIG = 2


def node_parser(prog: str, description: str) -> argparse.ArgumentParser:
    """An argument parser with the shared node flags."""
    parser = argparse.ArgumentParser(prog=prog, description=description)
    add_common_arguments(parser)
    parser.add_argument(
        "--name", dest="name", default=None, help="node name (default: the node kind)"
    )
    return parser


def sensor_node_parser(prog: str, description: str) -> argparse.ArgumentParser:
    """:func:`node_parser` with ``--sensor`` and ``--input`` (a sensor machine's node)."""
    parser = node_parser(prog, description)
    parser.add_argument("--sensor", required=True, help="sensor id in the network file")
    parser.add_argument(
        "--input", default=None, help="frame source instead of the sensor's own (see detect)"
    )
    return parser


def run_sensor_node(
    kind: str,
    parser: argparse.ArgumentParser,
    body: Callable[[NetworkConfig, Node, argparse.Namespace], None],
    argv: Sequence[str] | None = None,
) -> int:
    """:func:`run_node` under the sensor's detector name, unless ``--name`` says otherwise.

    The detector's name is what a secured site's sensor certificate is issued to.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    known, _ = parser.parse_known_args(argv)
    if "--name" not in argv:
        argv += ["--name", detector_node_name(known.sensor)]
    return run_node(kind, parser, body, argv)


def run_node(
    kind: str,
    parser: argparse.ArgumentParser,
    body: Callable[[NetworkConfig, Node, argparse.Namespace], None],
    argv: Sequence[str] | None = None,
) -> int:
    """Parse flags, load the network file, open the bus and run ``body`` in a node.

    Returns the process exit code: 0 after a clean stop (including Ctrl-C/SIGTERM),
    2 for configuration errors (printed, naming the key).
    """
    args = parser.parse_args(argv)
    name = args.name or kind
    configure_logging(name, args.log_level, args.log_format)
    try:
        if args.identity is not None and args.identity != name:
            raise ConfigError(
                f"--identity: a node authenticates as its own name ({name!r}); give "
                "--name to run it under another"
            )
        cfg = network_from_args(args)
        with (
            bus_from_args(cfg, args, identity=name) as bus,
            Node(name, bus, site=cfg.site, stats_interval_s=cfg.stats_interval_s) as node,
        ):
            node.install_signal_handlers()
            body(cfg, node, args)
    except ConfigError as exc:
        print(f"{parser.prog}: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    except KeyboardInterrupt:  # stopped while joining the network, before its handlers
        logging.getLogger(f"openptrack.{name}").info(
            "stopped", extra={"fields": {"during": "start-up"}}
        )
    return EXIT_OK
