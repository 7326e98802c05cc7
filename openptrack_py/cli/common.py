"""Pieces several ``openptrack`` subcommands share: exit code, result printing, options.

Kept light to import: modules needed only to run a command are imported inside the
functions that use them, so ``openptrack --help`` stays fast.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

from openptrack_py.errors import ConfigError
from openptrack_py.runtime.logs import LOG_LEVELS, configure_logging

if TYPE_CHECKING:
    from typing import TypeAlias

    from openptrack_py.config import DetectorConfig

    Subparsers: TypeAlias = argparse._SubParsersAction[argparse.ArgumentParser]

EXIT_CONFIG = 2
"""Exit status of a command refused for its configuration or arguments."""


def add_log_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--log-level`` and ``--log-format`` to a command without the bus flags."""
    parser.add_argument("--log-level", default="info", choices=LOG_LEVELS)
    parser.add_argument("--log-format", default="text", choices=("text", "json"))


def start_logging(args: argparse.Namespace) -> None:
    """Send the command's own logs to stderr as its ``--log-level``/``--log-format`` ask."""
    configure_logging("openptrack", args.log_level, args.log_format)


def pose_cells(pose: Any) -> dict[str, float]:
    """A pose's table cells: position in metres to 0.1 mm, angles in degrees to 0.001."""
    return {
        "x": round(pose.x, 4),
        "y": round(pose.y, 4),
        "z": round(pose.z, 4),
        "yaw_deg": round(pose.yaw_deg, 3),
        "pitch_deg": round(pose.pitch_deg, 3),
        "roll_deg": round(pose.roll_deg, 3),
    }


def print_rows(rows: list[dict], columns: list[str], fmt: str) -> None:
    """Print result rows as JSON (one object for one row), a Markdown table or a text table.

    Parameters
    ----------
    rows : list of dict
        One dict per result row.
    columns : list of str
        Columns of the Markdown and text tables, in order (JSON keeps every key).
    fmt : {"json", "markdown", "table"}
        Output format.
    """
    from openptrack_py.eval.runner import format_markdown, format_table

    if fmt == "json":
        one = len(rows) == 1
        print(json.dumps(rows[0] if one else rows, indent=None if one else 1))
    elif fmt == "markdown":
        print(format_markdown(rows, columns))
    else:
        print(format_table(rows, columns))


def add_detector_options(parser: argparse.ArgumentParser) -> None:
    """Add the detector settings ``detect`` and ``eval-detector`` share (see detector_config)."""
    from openptrack_py.config import HEIGHT_PRESETS

    parser.add_argument("--preset", choices=tuple(HEIGHT_PRESETS), help="height band preset")
    parser.add_argument("--detector-config", type=Path, help="YAML file of detector settings")
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE"
    )


def detector_config(args: argparse.Namespace) -> DetectorConfig:
    """The detector configuration the options of add_detector_options (and ``--ground``) ask for.

    Raises
    ------
    ConfigError
        If a setting is invalid, or ``--ground`` is neither ``auto`` nor four numbers.
    """
    from openptrack_py.config import DetectorConfig, load_config

    overrides = list(args.overrides)
    if args.preset:
        overrides.append(f"preset={args.preset}")
    if getattr(args, "ground", None):
        if args.ground == "auto":
            overrides.append("ground.mode=auto")
        else:
            try:
                plane = [float(v) for v in args.ground.split(",")]
            except ValueError:
                plane = []
            if len(plane) != 4:
                raise ConfigError(
                    f"--ground: expected 'auto' or four numbers a,b,c,d (received {args.ground!r})"
                )
            overrides += ["ground.mode=calibration", f"ground.plane=[{','.join(map(str, plane))}]"]
    return load_config(DetectorConfig, args.detector_config, overrides)


class ProgressLine:
    """One status line on stderr: rewritten in place on a terminal, a line each otherwise.

    Parameters
    ----------
    every_s : float
        Least time between two lines when not on a terminal (logs stay short).
    """

    def __init__(self, every_s: float = 5.0) -> None:
        import sys
        import time

        self._stream = sys.stderr
        self._tty = self._stream.isatty()
        self._every_s = every_s
        self._clock = time.monotonic
        self._last = -float("inf")
        self._shown = False

    def show(self, text: str) -> None:
        """Show ``text`` (rate-limited off a terminal)."""
        if not self._tty:
            if self._clock() - self._last < self._every_s:
                return
            self._last = self._clock()
        end = "" if self._tty else "\n"
        print(("\r\x1b[2K" if self._tty else "") + text, end=end, file=self._stream, flush=True)
        self._shown = True

    def done(self) -> None:
        """End the line on a terminal."""
        if self._tty and self._shown:
            print(file=self._stream, flush=True)


def bar(fraction: float, width: int = 24) -> str:
    """A text progress bar such as ``[#########-------]  52%``."""
    fraction = min(max(fraction, 0.0), 1.0)
    filled = round(fraction * width)
    return f"[{'#' * filled}{'-' * (width - filled)}] {100 * fraction:3.0f}%"
