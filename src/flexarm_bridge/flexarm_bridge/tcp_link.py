"""Opening the controller's TCP connection (pure: sockets only).

A connection to a port of this machine that nothing listens on can connect to itself: when
the port lies in the kernel's ephemeral range (Linux: 32768-60999; the shipped 47800 does) and
the kernel picks that same port as the connection's own, the SYN meets itself (a TCP
"simultaneous open"). A client that retries while the controller is down then holds the
controller's port, reads back what it sent, and the controller cannot bind when it starts.
Such a connection is refused here like one nothing answered, and reset rather than closed:
closed, it held the port in TIME_WAIT for a minute, and the controller still could not bind.
"""
from __future__ import annotations

import socket
import struct


def connect(host: str, port: int, timeout: float) -> socket.socket:
    """A TCP connection to ``host:port``; OSError if none (ConnectionRefusedError for one that
    met itself)."""
    sock = socket.create_connection((host, port), timeout=timeout)
    if sock.getsockname() == sock.getpeername():
        # reset, not closed: a closed connection stays in TIME_WAIT for a minute, and one
        # from a socket without SO_REUSEADDR keeps a server from binding the port meanwhile
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack('ii', 1, 0))
        sock.close()
        raise ConnectionRefusedError(f'{host}:{port}: the connection met itself (nothing '
                                     'listens there)')
    return sock
