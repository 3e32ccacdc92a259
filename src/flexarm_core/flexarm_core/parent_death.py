"""Processes that die with their parent: Linux's ``PR_SET_PDEATHSIG`` (prctl(2)).

The kernel sends the signal when the *thread* that created the process ends (not when the
whole parent process does), so the creating thread must live as long as the child should.
"""
from __future__ import annotations

import ctypes
import signal

PR_SET_PDEATHSIG = 1
# Looked up now: between fork and exec a child must not dlopen (another thread may hold the
# loader's lock).
_prctl = ctypes.CDLL(None, use_errno=True).prctl


def signal_on_parent_death(sig: int) -> None:
    """Have the kernel send ``sig`` to this process when its creating thread ends (0: no
    signal, undoing an inherited one)."""
    _prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0)


def terminate_with_parent() -> None:
    """A ``preexec_fn``: the child gets SIGTERM when the thread that starts it ends (its
    SIGKILL included), and stops what it started itself as on SIGTERM."""
    signal_on_parent_death(signal.SIGTERM)
