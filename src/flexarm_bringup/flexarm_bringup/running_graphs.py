"""Acting on the flexarm graphs running on this machine (:mod:`flexarm_core.graph_locks`
finds them), for ``flexarm ps`` and ``flexarm down``: which one a command means, stopping it,
and a table for people."""
from __future__ import annotations

import os
import select as io_select
import signal
from collections.abc import Iterable
from datetime import datetime

from flexarm_core.graph_locks import RunningGraph


class NoSuchGraph(LookupError):
    """No running graph matches what ``flexarm down`` was given."""


class AmbiguousGraph(LookupError):
    """Several running graphs match: the caller must say which."""


def select(graphs: Iterable[RunningGraph], domain_id: int | None = None,
           namespace: str | None = None) -> RunningGraph:
    """The one graph of ``graphs`` in ``domain_id`` (None: any) with ``namespace`` (None: any;
    '' the graph without one); NoSuchGraph or AmbiguousGraph, with the reason, otherwise."""
    graphs = list(graphs)
    ns = None if namespace is None else namespace.strip('/')
    matching = [g for g in graphs if (domain_id is None or g.domain_id == domain_id)
                and (ns is None or g.namespace == ns)]
    if len(matching) == 1:
        return matching[0]
    wanted = ' '.join(filter(None, [
        None if domain_id is None else f'in ROS domain {domain_id}',
        None if ns is None else (f'with namespace {ns}' if ns else 'without namespace')]))
    if not matching:
        if not graphs:
            raise NoSuchGraph('no flexarm graph runs on this machine')
        raise NoSuchGraph(f'no flexarm graph {wanted} runs on this machine; running:\n'
                          + graph_table(graphs))
    which = ('--domain-id' if len({g.domain_id for g in matching}) > 1 else '--namespace')
    raise AmbiguousGraph(f'{len(matching)} flexarm graphs run{" " + wanted if wanted else ""}:'
                         f' pass {which} to say which\n' + graph_table(matching))


def stop(graph: RunningGraph, timeout: float) -> bool:
    """SIGINT to the graph's supervisor, as Ctrl-C in its shell (it stops its nodes, then
    ends), and wait up to ``timeout`` seconds until it has ended; whether it has. Through a
    pidfd: the signal cannot reach another process that reused the pid, and its end is an
    event to wait on."""
    try:
        pidfd = os.pidfd_open(graph.supervisor_pid)
    except ProcessLookupError:
        return True
    try:
        signal.pidfd_send_signal(pidfd, signal.SIGINT)
        return bool(io_select.select([pidfd], [], [], timeout)[0])
    except ProcessLookupError:
        return True
    finally:
        os.close(pidfd)


def graph_table(graphs: Iterable[RunningGraph], now: float | None = None) -> str:
    """The graphs as a table for humans: domain, namespace, supervisor pid, start, robot,
    run folder."""
    now = datetime.now().timestamp() if now is None else now
    rows = [('DOMAIN', 'NAMESPACE', 'PID', 'STARTED', 'ROBOT', 'RUN')]
    rows += [(str(g.domain_id), g.namespace or '-', str(g.supervisor_pid),
              f'{datetime.fromtimestamp(g.started):%Y-%m-%d %H:%M:%S} '
              f'({_age(now - g.started)} ago)', g.robot, g.run_dir or '?') for g in graphs]
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]) - 1)]
    return '\n'.join('  '.join([*(cell.ljust(w) for cell, w in zip(row, widths)), row[-1]])
                     for row in rows)


def _age(seconds: float) -> str:
    seconds = max(seconds, 0.0)
    for unit, size in (('d', 86400), ('h', 3600), ('min', 60)):
        if seconds >= size:
            return f'{seconds / size:.1f} {unit}'
    return f'{seconds:.0f} s'
