"""``openptrack show-config``: a network file validated, with every default filled in."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from openptrack_py.config import load_network, to_yaml
from openptrack_py.runtime.args import resolve_config_path

if TYPE_CHECKING:
    from openptrack_py.cli.common import Subparsers


def add_parser(subparsers: Subparsers) -> None:
    """Register ``show-config``, its arguments and :func:`run`."""
    p = subparsers.add_parser(
        "show-config",
        help="validate a network file and print it with every default filled in",
    )
    p.add_argument("network", help="network file or preset name")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print the validated network file as YAML (a ConfigError ends the command)."""
    path = resolve_config_path(args.network)
    cfg = load_network(path, args.overrides)
    sys.stdout.write(to_yaml(cfg))
    return 0
