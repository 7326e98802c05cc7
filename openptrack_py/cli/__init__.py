"""The ``openptrack`` command.

Subcommands::

    openptrack launch NETWORK [--host NAME] [--duration S]   run this host's nodes
    openptrack node NAME [...]                               run one node in the foreground
    openptrack status [-c NETWORK]                           live nodes and their rates
    openptrack echo KEYEXPR [-c NETWORK]                     print messages as JSON lines
    openptrack config NODE [KEY=VALUE ...]                   change a running node's parameters
    openptrack eval --scenario NAME --seed N                 score a tracker on a scenario
    openptrack scenarios                                     list the simulated scenarios
    openptrack show-config NETWORK                           the validated network file
    openptrack record [-c NETWORK] [-o FILE.mcap]            record a running site
    openptrack replay FILE [--speed X] [--loop]              put a recording back on the bus
    openptrack retrack FILE [--set KEY=VALUE] [-o OUT]       re-run the tracker on a recording
    openptrack analyze FILE [--html REPORT] [-c NETWORK]     behaviour analytics of a recording
    openptrack record-sensor SOURCE OUTDIR                   record a depth source to a folder
    openptrack detect INPUT                                  detect people in depth frames
    openptrack eval-detector --scenario NAME                 score the detector on renderings
    openptrack certs init|issue|list FOLDER                  certificates of a secured site

``openptrack <subcommand> --help`` explains each. Each subcommand is one module of this
package with ``add_parser(subparsers)`` and ``run(args) -> int``; modules needed only to run a
command are imported inside its ``run``, so ``openptrack --help`` stays fast.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from openptrack_py import __version__
from openptrack_py.cli import (
    analyze,
    calibrate,
    certs,
    configure,
    detect,
    echo,
    eval_detector,
    eval_tracker,
    launch,
    node,
    record,
    record_sensor,
    replay,
    retrack,
    roster,
    scenarios,
    show_config,
    status,
)
from openptrack_py.cli.common import EXIT_CONFIG
from openptrack_py.cli.launch import RGBD_START_DELAY_S
from openptrack_py.cli.node import available_nodes
from openptrack_py.errors import ConfigError

__all__ = ["EXIT_CONFIG", "RGBD_START_DELAY_S", "available_nodes", "build_parser", "main"]

COMMANDS = (
    launch,
    node,
    status,
    echo,
    configure,
    roster,
    eval_tracker,
    record,
    replay,
    retrack,
    analyze,
    scenarios,
    show_config,
    record_sensor,
    detect,
    eval_detector,
    calibrate,
    certs,
)
"""The subcommand modules, in the order ``openptrack --help`` lists them."""


def build_parser() -> argparse.ArgumentParser:
    """The ``openptrack`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="openptrack",
        description="Multi-sensor people tracking for creative apps.",
    )
    parser.add_argument("--version", action="version", version=f"openptrack {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for command in COMMANDS:
        command.add_parser(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``openptrack`` command."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except ConfigError as exc:
        print(f"openptrack {args.command}: {exc}", file=sys.stderr)
        return EXIT_CONFIG


def console() -> int:
    """The ``openptrack`` program: :func:`main` with its standard output its own.

    Native libraries' writes to standard output (Zenoh's log lines) go to standard
    error (:func:`~openptrack_py.cli.streams.separate_native_stdout`), so what a command
    prints (JSON lines, tables) is never interleaved with them.
    """
    from openptrack_py.cli.streams import separate_native_stdout

    separate_native_stdout()
    return main()
