"""``openptrack scenarios``: list the simulated scenarios, one line each."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers


def add_parser(subparsers: Subparsers) -> None:
    """Register ``scenarios`` and :func:`run`."""
    p = subparsers.add_parser("scenarios", help="list the simulated scenarios")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print each scenario's name and description."""
    from openptrack_py.sim.scenarios import describe_scenarios

    for name, text in describe_scenarios().items():
        print(f"{name:13s} {text}")
    return 0
