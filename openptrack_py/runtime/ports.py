"""Free loopback ports for tests, benchmarks and throwaway local networks."""

from __future__ import annotations

import socket


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    """A port on 127.0.0.1 that was free a moment ago.

    Binds port 0, lets the operating system pick a free one, reads it back and closes the
    socket. Another process may take the port before the caller binds it, so this suits
    tests and local runs, not production configuration.

    Parameters
    ----------
    kind : int
        ``socket.SOCK_STREAM`` for a TCP port (e.g. a Zenoh endpoint or a web server),
        ``socket.SOCK_DGRAM`` for a UDP port.

    Returns
    -------
    int
        The port number.
    """
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]
