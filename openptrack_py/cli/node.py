"""``openptrack node``: run one of the shipped nodes in the foreground."""

from __future__ import annotations

import argparse
import os
import pkgutil
import sys
from typing import TYPE_CHECKING

from openptrack_py.cli.common import EXIT_CONFIG
from openptrack_py.cli.streams import restore_native_stdout

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers


def available_nodes() -> list[str]:
    """Names of the node modules shipped in ``openptrack_py.nodes``."""
    import openptrack_py.nodes as package

    return sorted(m.name for m in pkgutil.iter_modules(package.__path__) if not m.ispkg)


def add_parser(subparsers: Subparsers) -> None:
    """Register ``node``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
        "node",
        help="run one node in the foreground",
        description="Run one node. Available nodes: "
        + ", ".join(available_nodes())
        + ". Arguments after the name go to the node (see 'openptrack node NAME --help').",
    )
    p.add_argument("name", help="node name")
    p.add_argument("node_args", nargs=argparse.REMAINDER, help="arguments for the node")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Replace this process with the node's (``python -m openptrack_py.nodes.NAME``)."""
    nodes = available_nodes()
    if args.name not in nodes:
        print(
            f"openptrack node: unknown node {args.name!r} (available: {', '.join(nodes)})",
            file=sys.stderr,
        )
        return EXIT_CONFIG
    module = f"openptrack_py.nodes.{args.name}"
    restore_native_stdout()
    os.execv(sys.executable, [sys.executable, "-m", module, *args.node_args])
    return 0  # pragma: no cover - execv does not return
