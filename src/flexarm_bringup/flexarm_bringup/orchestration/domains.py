"""ROS domain ids reserved on this machine, the way ros-jazzy-domain-coordinator does it
(binding TCP port 32768 + id: whoever holds the port has the domain), so parallel test runs,
benchmarks and graphs never share one by accident.

domain_coordinator's own ``domain_id()`` context manager is not used: it catches ``OSError``
around its ``yield``, so a ``TimeoutError`` (an OSError) raised by the code using the domain
becomes "generator didn't stop after throw()", and its selector starts at 1 on every call.
"""
from __future__ import annotations

import contextlib
import socket
from collections.abc import Iterator

from domain_coordinator.impl import PORT_BASE

FIRST, LAST = 1, 100     # domain_coordinator's range
MAX_DOMAIN_ID = 232      # the largest ROS_DOMAIN_ID whose DDS ports exist


def hold(domain_id: int) -> socket.socket | None:
    """The socket that reserves ``domain_id`` while it stays open; None if it is taken."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        sock.bind(('', PORT_BASE + domain_id))
    except OSError:
        sock.close()
        return None
    return sock


def first_free() -> tuple[int, socket.socket]:
    """The first free domain and the socket that reserves it; RuntimeError if none is."""
    for candidate in range(FIRST, LAST + 1):
        sock = hold(candidate)
        if sock is not None:
            return candidate, sock
    raise RuntimeError(f'no free ROS domain in {FIRST}..{LAST} on this machine')


@contextlib.contextmanager
def reserved(domain_id: int | None = None) -> Iterator[int]:
    """``domain_id`` as given, or the first free one reserved until the block ends."""
    if domain_id is not None:
        yield domain_id
        return
    candidate, sock = first_free()
    with sock:
        yield candidate
