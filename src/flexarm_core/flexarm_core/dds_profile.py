"""Fast DDS's profiles file, and flexarm's own that keeps a process's transports on this
machine (shared memory and UDPv4 on the loopback interface, ``config/fastdds/localhost.xml``):
the launcher gives it to a graph confined to this machine, and a node that runs with it knows
that every participant it meets runs on this machine too."""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from flexarm_core.params import config_path

PROFILES_ENV = 'FASTRTPS_DEFAULT_PROFILES_FILE'   # the name Fast DDS 2.14 (Jazzy) reads


def localhost_profile() -> str:
    """Path of the profile that keeps every transport on this machine."""
    return str(config_path('fastdds/localhost.xml'))


def on_this_machine_only(env: Mapping[str, str]) -> bool:
    """Whether a process of ``env`` reaches participants of this machine alone (it runs with
    :func:`localhost_profile`)."""
    path = env.get(PROFILES_ENV)
    return bool(path) and Path(path).resolve() == Path(localhost_profile()).resolve()
