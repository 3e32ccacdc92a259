"""Who sent an action goal, and whether they are still there (pure core: the nodes hand it
the graph; no rclpy here).

rclpy does not tell an action server which client sent a goal, so the server keeps the goal's
**candidates**: at acceptance, every client of the action it has discovered, one per DDS
participant (the first 12 bytes of an endpoint's gid, the RTPS GUID prefix). A client is
known by its ``send_goal`` request writer (``rq<action>/_action/send_goalRequest``, ROS 2's
DDS name of a service's requests): a server receives requests only from writers it has
discovered, so the sender is always among the candidates, and tools that merely watch a
goal's feedback or status are not. The goal is **abandoned** when no candidate remains. With
several candidates it lives as long as any of them: the sender cannot be told apart from
another client of the action, and cancelling a goal whose sender is alive would be worse than
keeping an abandoned one (``flexarm cancel`` and the server's time limit end that).

A candidate is gone when discovery no longer lists its writer, or when its process has ended.
DDS forgets a killed participant only after its lease (Fast DDS: 20 s), but a client on this
machine is known dead at once from its process: Fast DDS (vendor id 01.0f) puts a host id in
bytes 2-3 of the GUID prefix and the low 16 bits of the process id in bytes 4-5. A candidate
on this machine is remembered at acceptance with the live processes whose id has those low
bits (id and start time, so a reused id is not taken for it), and is gone once they have all
ended. A candidate is on this machine when the server's transports reach no other (flexarm's
localhost profile: :mod:`flexarm_core.dds_profile`), else when its GUID has the server's host
id. That id is a hash of the host name and of the IPv4 addresses the process saw when it
started, so a process started while a network interface was up (a VPN, a container's bridge, a
test's veth) has another: the server cannot tell it from a remote client by it. A client on
another host, or in a process this machine's process list does not show (another PID namespace),
is judged by discovery alone.
"""
from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from typing import Any, Protocol

import psutil

from flexarm_core.processes import start_time

Endpoint = tuple[bytes, str]      # (endpoint gid, full node name)
Process = tuple[int, int]         # (process id, start in clock ticks: processes.start_time)
FASTDDS = b'\x01\x0f'             # RTPS vendor id of eProsima Fast DDS
UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'   # what discovery reports before it knows the name
_SENDER = re.compile(r'goal sent by ((?:one of )?[^;()]+)')


class Graph(Protocol):
    """What is read of the ROS graph: rclpy's ``Node`` has it."""

    def get_publishers_info_by_topic(self, topic_name: str, no_mangle: bool = False
                                     ) -> list[Any]: ...


def send_goal_writers(graph: Graph, action: str) -> list[Endpoint]:
    """One ``(gid, node name)`` per client of ``action`` (its absolute name) in the graph."""
    infos = graph.get_publishers_info_by_topic(f'rq{action}/_action/send_goalRequest',
                                               no_mangle=True)
    return [(bytes(i.endpoint_gid), full_name(i.node_namespace, i.node_name)) for i in infos]


def full_name(namespace: str, name: str) -> str:
    """``/ns/node`` ('?' for a node discovery has not named yet)."""
    if not name or name == UNKNOWN_NODE:
        return '?'
    return f'{namespace.rstrip("/")}/{name}'


def participant(gid: bytes) -> bytes:
    """The DDS participant (RTPS GUID prefix) of an endpoint gid."""
    return bytes(gid[:12])


def process_bits(gid: bytes, host: bytes | None) -> int | None:
    """The low 16 bits of the process id of a Fast DDS endpoint of the host whose gid starts
    with ``host`` (any gid of that host; None: any host), or None (another vendor or host)."""
    if gid[:2] != FASTDDS or host is not None and (host[:2] != FASTDDS
                                                   or gid[2:4] != host[2:4]):
        return None
    return gid[4] | gid[5] << 8


class Processes(Protocol):
    """The processes of this machine, as far as the candidates need them."""

    def with_bits(self, bits: int) -> frozenset[Process]:
        """The live processes whose id has these low 16 bits."""

    def alive(self, process: Process) -> bool:
        """Whether the process still runs (the same one: its start time)."""


class ProcTable:
    """:class:`Processes` of this machine, by psutil (a zombie counts as ended)."""

    def with_bits(self, bits: int) -> frozenset[Process]:
        return frozenset((pid, start) for pid in psutil.pids()
                         if pid & 0xFFFF == bits and (start := start_time(pid)) is not None)

    def alive(self, process: Process) -> bool:
        return start_time(process[0]) == process[1]


@dataclass(frozen=True)
class Candidate:
    """One client that may have sent the goal."""

    participant: bytes
    name: str
    processes: frozenset[Process] = frozenset()   # empty: known by discovery only

    def present(self, participants: set[bytes], alive: Callable[[Process], bool]) -> bool:
        return self.participant in participants and (
            not self.processes or any(alive(p) for p in self.processes))


@dataclass(frozen=True)
class GoalSender:
    """The candidates of one goal (module docstring); none: the sender is unknown."""

    candidates: tuple[Candidate, ...] = ()

    @property
    def names(self) -> list[str]:
        return sorted({c.name for c in self.candidates})

    def text(self) -> str:
        """'goal sent by /node' (or 'by one of …'), in the form :func:`sender_of` reads."""
        names = self.names
        if not names:
            return 'sender unknown'
        return 'goal sent by ' + ('one of ' if len(names) > 1 else '') + ', '.join(names)

    def named(self, writers: Iterable[Endpoint]) -> GoalSender:
        """The candidates with the names ``writers`` give them now: a node discovery had not
        named yet at acceptance ('?') is named once it has."""
        known: dict[bytes, set[str]] = {}
        for gid, name in writers:
            if name != '?':
                known.setdefault(participant(gid), set()).add(name)
        return GoalSender(tuple(
            replace(c, name=', '.join(sorted(known[c.participant])))
            if '?' in c.name.split(', ') and c.participant in known else c
            for c in self.candidates))

    def by_discovery_only(self) -> list[str]:
        """Names of the candidates known by discovery alone (no process of this machine)."""
        return sorted({c.name for c in self.candidates if not c.processes})

    def gone(self, writers: Iterable[Endpoint], alive: Callable[[Process], bool]) -> bool:
        """Whether no candidate remains among the action's ``writers`` (never for a sender
        without candidates: nothing to judge by)."""
        participants = {participant(gid) for gid, _ in writers}
        return bool(self.candidates) and not any(
            c.present(participants, alive) for c in self.candidates)


def sender_at_acceptance(writers: Iterable[Endpoint], host: bytes | None,
                        processes: Processes, this_machine_only: bool = False) -> GoalSender:
    """The sender of a goal accepted now: the action's ``writers`` (one per client) by
    participant, each with its processes when it runs on the host of the gid ``host`` (the
    server's own; None: unknown), or on any host when ``this_machine_only`` (the server's
    transports reach this machine alone, so every client runs here)."""
    names: dict[bytes, set[str]] = {}
    bits: dict[bytes, int | None] = {}
    for gid, name in writers:
        key = participant(gid)
        names.setdefault(key, set()).add(name)
        bits[key] = (process_bits(gid, None) if this_machine_only else
                     None if host is None else process_bits(gid, host))
    return GoalSender(tuple(
        Candidate(key, ', '.join(sorted(names[key])),
                  frozenset() if bits[key] is None else processes.with_bits(bits[key]))
        for key in sorted(names)))


def sender_of(text: str) -> str:
    """The sender an :meth:`GoalSender.text` in ``text`` names ('' if none)."""
    found = _SENDER.search(text)
    return found.group(1).strip() if found else ''


def own_participant(writers: Iterable[Endpoint], name: str, pid: int) -> bytes | None:
    """Among ``writers``, the participant of this process's node ``name`` (full name): its
    Fast DDS process bits tell it from other processes' nodes of the same name."""
    for gid, writer_name in writers:
        if writer_name == name and gid[:2] == FASTDDS and (gid[4] | gid[5] << 8) == pid & 0xFFFF:
            return participant(gid)
    return None
