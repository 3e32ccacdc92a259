"""Wall-clock liveness limits, scaled for loaded machines.

Whether a peer is alive (a controller that stopped publishing joint states, an action server
that stopped answering, a node that never showed up in discovery) can only be told in wall
time: a dead process sends no event, and a stopped ``/clock`` stops sim time too. Every such
limit is written for an ordinary machine and multiplied by ``FLEXARM_LIVENESS_SCALE`` (default
1). On a machine whose cores are all busy (a CI runner, the test suite running two workers) a
live process can be starved for seconds, so the test suite sets the factor to
:data:`UNDER_TEST`; an operator on a loaded controller PC may raise it too. Every other wait
is on an event or on simulated time and needs no factor.
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


def limit(seconds: float) -> float:
    """A wall-clock liveness limit of ``seconds`` on an ordinary machine, scaled."""
    return seconds * scale()
