"""Telling a restarted controller from the one a command went to (pure: the ROS shell hands
it the publishers of ``/joint_states``).

A controller node that dies and comes back within the silence that tells a move its controller
is gone (``JOINT_SILENCE``: a respawned bridge is back in about a second) publishes joint states
again, but the command it held died with it: the move would wait out its whole time limit for
an arm that was never told to go. The new incarnation has the old one's node name and a new
endpoint gid, and that is what ends the move at once. A publisher of another name is another
node, not a restart; one discovery has not named yet ('?') is not judged.
"""
from __future__ import annotations

from collections.abc import Iterable

Endpoint = tuple[bytes, str]      # (endpoint gid, full node name)


def restarted(at_command: Iterable[Endpoint], now: Iterable[Endpoint]) -> list[str]:
    """The node names publishing ``now`` under a gid they did not have ``at_command``."""
    before: dict[str, set[bytes]] = {}
    for gid, name in at_command:
        before.setdefault(name, set()).add(gid)
    return sorted({name for gid, name in now
                   if name != '?' and name in before and gid not in before[name]})
