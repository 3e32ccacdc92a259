"""Wall-clock liveness limits, scaled for loaded machines.

Whether a peer is alive (a controller that stopped publishing joint states, an action server
that stopped answering, a node that never showed up in discovery) can only be told in wall
time: a dead process sends no event, and a stopped ``/clock`` stops sim time too. Every such
limit is written for an ordinary machine and multiplied by a factor, the larger of two: the
machine's load (the 1-minute load average per core, when above 1: a live process waiting for a
core among N runnable ones answers N times later) and ``FLEXARM_LIVENESS_SCALE`` (default 1), a
floor for starvation the load average is too slow to show (the test suite sets
:data:`UNDER_TEST`: its workers start bursts of nodes; an operator on a loaded controller PC may
raise it too). So a peer is declared dead later on a busy machine, never early. Every other
wait is on an event or on simulated time and needs no factor.
"""
from __future__ import annotations

import os

ENV = 'FLEXARM_LIVENESS_SCALE'
UNDER_TEST = 4.0   # the factor the test suite sets (conftest.py)


def scale() -> float:
    """The factor of the environment (1 when unset); a bad value is an error, not ignored."""
    text = os.environ.get(ENV, '').strip()
    if not text:
        return 1.0
    value = float(text)
    if not value > 0:
        raise ValueError(f'{ENV} must be a positive number, not {text!r}')
    return value


def load() -> float:
    """Runnable processes per core this process may use (1-minute load average), at least 1."""
    return max(1.0, os.getloadavg()[0] / len(os.sched_getaffinity(0)))


def limit(seconds: float) -> float:
    """A wall-clock liveness limit of ``seconds`` on an ordinary idle machine, scaled by the
    environment's factor or the machine's load, whichever is larger."""
    return seconds * max(scale(), load())
