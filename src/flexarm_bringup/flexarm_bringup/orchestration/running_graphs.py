"""The flexarm graphs running on this machine, for ``flexarm ps`` and ``flexarm down``.

A graph's supervisor holds an flock on its domain's lock file (``supervisor.lock_name``, in
``supervisor.LOCK_DIR``) for as long as it runs; the kernel drops the lock when the process
ends, however it ends, so a held lock is what "live" means here (a pid written in the file may
have been reused since). Who holds a lock is read from ``/proc/locks`` without touching it: a
probe that took the lock itself, even for a moment, could make a ``flexarm up`` starting just
then refuse the domain. The run folder's graph record (``supervisor.RECORD``) adds the robot
and the run folder. No rclpy: this is files and processes only.
"""
from __future__ import annotations

import json
import os
import select as io_select
import signal
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from datetime import datetime
from pathlib import Path

from flexarm_bringup.orchestration.supervisor import RECORD, parse_lock_name

PROC_LOCKS = Path('/proc/locks')


def lock_holders(proc_locks: str) -> dict[tuple[int, int, int], int]:
    """(device major, minor, inode): pid of every FLOCK in ``/proc/locks``' text."""
    holders = {}
    for line in proc_locks.splitlines():
        fields = line.split()
        if len(fields) < 6 or fields[1] != 'FLOCK':
            continue            # another kind, or '->': a process waiting for the lock
        try:
            major, minor, inode = fields[5].split(':')
            holders[int(major, 16), int(minor, 16), int(inode)] = int(fields[4])
        except ValueError:
            continue
    return holders


def lock_holder(path: Path, holders: dict[tuple[int, int, int], int]) -> int | None:
    """The pid holding an flock on ``path`` (per :func:`lock_holders`), None if none does."""
    try:
        st = path.stat()
    except OSError:
        return None
    return holders.get((os.major(st.st_dev), os.minor(st.st_dev), st.st_ino))


@dataclass(frozen=True)
class RunningGraph:
    """A live graph of this machine: its domain, arm, supervisor and when it took the domain
    (``started``: seconds since the epoch, the lock file's last write)."""

    domain_id: int
    namespace: str
    supervisor_pid: int
    started: float
    robot: str = '?'
    run_dir: str = ''
    nodes: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, object]:
        return asdict(self) | {'nodes': list(self.nodes)}


def running_graphs(lock_dir: Path, runs_dir: Path, proc_locks: Path = PROC_LOCKS
                   ) -> list[RunningGraph]:
    """Every graph whose supervisor holds its lock in ``lock_dir``, by domain and namespace,
    with what its record under ``runs_dir`` says."""
    try:
        holders = lock_holders(proc_locks.read_text())
    except OSError:
        holders = {}
    records = _records(runs_dir)
    graphs = []
    for path in sorted(Path(lock_dir).glob('*.lock')):
        key, pid = parse_lock_name(path.name), lock_holder(path, holders)
        if key is None or pid is None:
            continue
        try:
            started = path.stat().st_mtime
        except OSError:
            continue            # stopped meanwhile
        record = records.get((pid, *key), {})
        graphs.append(RunningGraph(
            key[0], key[1], pid, started, str(record.get('robot', '?')),
            str(record.get('run_dir', '')), tuple(record.get('nodes', {}))))
    return sorted(graphs, key=lambda g: (g.domain_id, g.namespace))


def _records(runs_dir: Path) -> dict[tuple[int, int, str], dict[str, object]]:
    """The graph records under ``runs_dir`` by (supervisor pid, domain id, namespace), the
    newest where a pid was reused."""
    found: dict[tuple[int, int, str], dict[str, object]] = {}
    paths = sorted(Path(runs_dir).glob(f'*/{RECORD}'), key=_mtime)
    for path in paths:
        try:
            record = json.loads(path.read_text())
            key = (int(record['supervisor_pid']), int(record['domain_id']),
                   str(record.get('namespace', '')))
        except (OSError, ValueError, KeyError, TypeError):
            continue
        found[key] = record | {'run_dir': str(path.parent)}
    return found


def _mtime(path: Path) -> float:
    try:
        return path.stat().st_mtime
    except OSError:
        return 0.0


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
