"""A command's standard output carries only what the command prints.

Zenoh's logger (Rust ``tracing``, set up by ``zenoh.init_log_from_env_or``) writes to
file descriptor 1 whatever Python's ``sys.stdout`` is, so a command that prints JSON
lines or a table while a session is open can have a log line land among them (seen:
an ERROR ``Received Data for unknown expr_id`` as a session starts, between the JSON
lines of a subscriber). :func:`separate_native_stdout` gives Python's ``sys.stdout`` a
descriptor of its own on the original standard output and points descriptor 1 at
standard error, where every log goes.
"""

from __future__ import annotations

import io
import os
import sys


def separate_native_stdout() -> bool:
    """Keep ``sys.stdout`` on standard output and send other writes to descriptor 1 to stderr.

    Done once, at the start of a command run as a program (not by :func:`main
    <openptrack_py.cli.main>` called in-process, whose caller owns the streams). Child
    processes started afterwards with an inherited standard output write to standard
    error too; the launcher gives its children pipes of their own.

    Returns
    -------
    bool
        Whether the streams were separated (not when ``sys.stdout`` is not descriptor 1,
        e.g. already replaced by a caller).
    """
    old = sys.stdout
    if _descriptor(old) != 1:
        return False
    old.flush()
    kept = os.dup(1)  # not inherited by child processes
    os.dup2(2, 1)
    raw = io.FileIO(kept, "w", closefd=True)
    binary = raw if isinstance(old.buffer, io.RawIOBase) else io.BufferedWriter(raw)
    sys.stdout = io.TextIOWrapper(
        binary,  # type: ignore[arg-type]
        encoding=old.encoding,
        errors=old.errors,
        line_buffering=old.line_buffering,
        write_through=old.write_through,
    )
    return True


def restore_native_stdout() -> None:
    """Point descriptor 1 back at standard output (before ``os.exec*`` replaces the process).

    The program that follows writes to descriptor 1 itself; without this its output
    would go to standard error.
    """
    out = sys.stdout
    fd = _descriptor(out)
    if fd is not None and fd != 1:
        out.flush()
        os.dup2(fd, 1)


def _descriptor(stream: object) -> int | None:
    """The file descriptor under ``stream``, or ``None`` (no stream, or not a file)."""
    try:
        return stream.fileno()  # type: ignore[attr-defined, no-any-return]
    except (AttributeError, OSError, ValueError, io.UnsupportedOperation):
        return None
