"""Command-line flags shared by every node and network command (zenoh-examples style)."""

from __future__ import annotations

import argparse
import importlib.resources
import os
from pathlib import Path

from openptrack_py.config import NetworkConfig, ZenohConfig, load_network, validate_config
from openptrack_py.config.network import OPERATOR
from openptrack_py.errors import ConfigError
from openptrack_py.runtime.logs import LOG_LEVELS
from openptrack_py.security.policy import session_settings
from openptrack_py.transport.zenoh_bus import ZenohBus, endpoints_from_flags


def presets_dir() -> Path:
    """Folder of the network files shipped with the package (``config/`` in the source)."""
    return Path(str(importlib.resources.files("openptrack_py.presets")))


def resolve_config_path(value: str | None) -> Path | None:
    """Find a network file: a path, or the name of a shipped preset (``demo``).

    Raises
    ------
    ConfigError
        If neither a file nor a preset of that name exists.
    """
    if value is None:
        return None
    path = Path(value)
    if path.exists():
        return path
    folder = presets_dir()
    for candidate in (folder / value, folder / f"{value}.yaml"):
        if candidate.is_file():
            return candidate
    presets = sorted(p.stem for p in folder.glob("*.yaml"))
    raise ConfigError(
        f"config: no file {value!r} and no preset of that name (presets: {', '.join(presets)})"
    )


def add_common_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``-c``, ``--set``, Zenoh and logging flags to ``parser``."""
    parser.add_argument(
        "-c",
        "--config",
        dest="config",
        metavar="NETWORK",
        default=os.environ.get("OPENPTRACK_CONFIG"),
        help="network file (YAML) or preset name such as 'demo' [env OPENPTRACK_CONFIG]",
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        metavar="KEY=VALUE",
        action="append",
        default=[],
        help="override a config value, e.g. --set sim.seed=3 (repeatable)",
    )
    add_zenoh_arguments(parser)
    logs = parser.add_argument_group("logging")
    logs.add_argument("--log-level", dest="log_level", choices=LOG_LEVELS, default="info")
    logs.add_argument("--log-format", dest="log_format", choices=("text", "json"), default="text")


def add_zenoh_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the Zenoh flags (``--mode``, ``-e``, ``-l``, scouting, ``--identity``)."""
    zenoh = parser.add_argument_group("zenoh")
    zenoh.add_argument(
        "--mode", dest="mode", choices=("peer", "client"), help="zenoh session mode"
    )
    zenoh.add_argument(
        "-e",
        "--connect",
        dest="connect",
        metavar="ENDPOINT",
        action="append",
        help="endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable; replaces the hub)",
    )
    zenoh.add_argument(
        "-l",
        "--listen",
        dest="listen",
        metavar="ENDPOINT",
        action="append",
        help="endpoint to listen on (repeatable)",
    )
    zenoh.add_argument(
        "--multicast-scouting",
        dest="multicast_scouting",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="discover peers by UDP multicast (off unless the network file says otherwise)",
    )
    zenoh.add_argument(
        "--identity",
        dest="identity",
        metavar="NAME",
        default=None,
        help="certificate to authenticate with when the network has a 'security' section "
        "(default: the node name; 'operator' for command-line tools)",
    )


def network_from_args(args: argparse.Namespace) -> NetworkConfig:
    """Load the network file named by ``-c`` with ``--set`` overrides applied."""
    return load_network(resolve_config_path(args.config), args.overrides)


def zenoh_from_args(cfg: ZenohConfig, args: argparse.Namespace) -> ZenohConfig:
    """Apply ``--mode``, ``-e``, ``-l`` and ``--multicast-scouting`` to ``cfg``."""
    update: dict[str, object] = {}
    if args.mode is not None:
        update["mode"] = args.mode
    connect = endpoints_from_flags(args.connect)
    if connect is not None:
        # Explicit endpoints replace the hub: the user says where to go.
        update["connect"] = connect
        update["hub"] = None
    listen = endpoints_from_flags(args.listen)
    if listen is not None:
        update["listen"] = listen
    if args.multicast_scouting is not None:
        update["multicast_scouting"] = args.multicast_scouting
    if not update:
        return cfg
    return validate_config(ZenohConfig, {**cfg.model_dump(), **update}, "zenoh flags (-e, -l)")


def bus_from_args(
    cfg: NetworkConfig, args: argparse.Namespace, identity: str = OPERATOR
) -> ZenohBus:
    """Open the Zenoh session described by the network file and the flags.

    Parameters
    ----------
    cfg : NetworkConfig
        The network file.
    args : argparse.Namespace
        Parsed flags (:func:`add_common_arguments`).
    identity : str
        Certificate used when the network is secured, unless ``--identity`` names another.
    """
    settings = session_settings(cfg, getattr(args, "identity", None) or identity)
    return ZenohBus(zenoh_from_args(cfg.zenoh, args), settings=settings)
