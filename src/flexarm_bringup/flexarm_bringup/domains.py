"""ROS domain ids reserved on this machine, the way ros-jazzy-domain-coordinator does it
(binding TCP port 32768 + id: whoever holds the port has the domain), so parallel test runs,
benchmarks and graphs never share one by accident.

domain_coordinator's own ``domain_id()`` context manager is not used: it catches ``OSError``
around its ``yield``, so a ``TimeoutError`` (an OSError) raised by the code using the domain
becomes "generator didn't stop after throw()", and its selector starts at 1 on every call.
"""
from __future__ import annotations

import contextlib
import os
import socket
from collections.abc import Iterable, Iterator, Mapping

from domain_coordinator.impl import PORT_BASE

from flexarm_core import processes

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


def in_use() -> set[int]:
    """The domains live processes of this machine run in, as their environment's
    ROS_DOMAIN_ID says (this process and those not ours to read left out): a process started
    in a domain holds no reservation of it, a ``ros2`` tool or another vendor's node, say."""
    own = os.getpid()
    return domain_ids(env for pid, env in processes.environments().items() if pid != own)


def domain_ids(environments: Iterable[Mapping[str, str]]) -> set[int]:
    """The ROS_DOMAIN_ID each of ``environments`` names, read as rcl does (an empty one names
    none)."""
    found: set[int] = set()
    for env in environments:
        with contextlib.suppress(ValueError):
            found.add(int(env.get('ROS_DOMAIN_ID', '')))
    return found


def first_free() -> tuple[int, socket.socket]:
    """The first domain nobody reserved and no process of this machine runs in
    (:func:`in_use`), and the socket that reserves it; RuntimeError if none is."""
    busy = in_use()
    for candidate in range(FIRST, LAST + 1):
        if candidate in busy:
            continue
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
