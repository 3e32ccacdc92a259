"""Which Fast DDS transports a flexarm process uses: confined to this machine unless widened.

The Fast DDS of the PyPI wheels has no DDS-Security, so any participant that reaches the graph
can command the arm. ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` alone does not keep it on this
machine: it only narrows whom a node announces itself to, while the built-in UDPv4 transport
listens on every interface, and a remote peer that names this host in its ``ROS_STATIC_PEERS``
gets in. ``config/fastdds/localhost.xml`` replaces the built-in transports by shared memory and
UDPv4 on the loopback interface only. A process whose discovery range is LOCALHOST (or OFF) gets
that profile; one exposed on purpose (another range, or ``ROS_STATIC_PEERS`` naming other hosts)
gets Fast DDS's defaults and a warning (:func:`warning`). A profiles file the user set is kept
either way: tuned transports are theirs to decide, and :func:`warning` says that they decide.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping, MutableMapping

from flexarm_core.dds_profile import PROFILES_ENV, localhost_profile

RANGE_ENV = 'ROS_AUTOMATIC_DISCOVERY_RANGE'
PEERS_ENV = 'ROS_STATIC_PEERS'
# '1': Fast DDS skips DEFAULT_FASTRTPS_PROFILES.xml of the working directory, which it would
# load after PROFILES_ENV's file and whose default profile would then win.
SKIP_CWD_ENV = 'SKIP_DEFAULT_XML_FILE'
CONFINED_RANGES = ('LOCALHOST', 'OFF')


def exposed(env: Mapping[str, str]) -> bool:
    """Whether a process of ``env`` is meant to be reachable from other hosts: a discovery
    range beyond LOCALHOST (unset is rcl's default, SUBNET), or static peers."""
    return (env.get(RANGE_ENV, '').strip().upper() not in CONFINED_RANGES
            or bool(env.get(PEERS_ENV, '').strip()))


def users_profile(env: Mapping[str, str]) -> str | None:
    """The profiles file the user set in ``env`` (not flexarm's), or None."""
    path = env.get(PROFILES_ENV, '')
    return path if path and path != localhost_profile() else None


def transport_env(env: Mapping[str, str]) -> dict[str, str]:
    """``env`` with the profile its discovery range calls for: the localhost profile (and none
    from the working directory) unless :func:`exposed`, else without it. The two variables are
    set and removed together; a user's profiles file is left as it is."""
    out = dict(env)
    if users_profile(out):
        return out
    if exposed(out):
        if out.pop(PROFILES_ENV, None):
            out.pop(SKIP_CWD_ENV, None)
    else:
        out[PROFILES_ENV], out[SKIP_CWD_ENV] = localhost_profile(), '1'
    return out


def apply(environ: MutableMapping[str, str]) -> None:
    """Bring ``environ`` (``os.environ`` before the process's first ROS participant: Fast DDS
    reads its profile once per process) to :func:`transport_env`."""
    wanted = transport_env(environ)
    for key in (PROFILES_ENV, SKIP_CWD_ENV):
        if key in wanted:
            environ[key] = wanted[key]
        else:
            environ.pop(key, None)


def profile_problem(env: Mapping[str, str]) -> str | None:
    """Why the profiles file of ``env`` cannot be used, None if it can or none is set. Fast DDS
    takes a file it cannot read or parse for none: it logs a line and runs with its defaults,
    the built-in transports, which open a graph meant for this machine to the network."""
    path = env.get(PROFILES_ENV)
    if not path:
        return None
    try:
        ET.parse(path)
    except (OSError, ET.ParseError) as exc:
        return (f'the Fast DDS profiles file {path} ({PROFILES_ENV}) cannot be used: {exc}. '
                'Fast DDS would ignore it and run with its defaults; nothing was started')
    return None


def warning(env: Mapping[str, str]) -> str | None:
    """What the operator must be told about who can reach a graph started with ``env``, or
    None when only this machine can."""
    if exposed(env):
        peers = env.get(PEERS_ENV, '').strip()
        how = f'{PEERS_ENV}={peers}' if peers else (
            f'discovery range {env.get(RANGE_ENV, "").strip().upper() or "SUBNET"}')
        return (f'WARNING: the graph is open to the network ({how}): anyone on that network '
                'who joins this ROS domain can command the arm (publish joint commands, send '
                'goals). The Fast DDS of these wheels has no DDS-Security; use a dedicated, '
                'trusted network.')
    if users_profile(env):
        return (f'note: Fast DDS profiles from {users_profile(env)} ({PROFILES_ENV}): its '
                "transports, not flexarm's localhost profile, decide who can reach the graph.")
    return None
