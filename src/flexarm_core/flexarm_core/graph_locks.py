"""The flexarm graphs running on this machine, and the domain a client finds its graph in.

A graph's supervisor holds an flock on its domain's lock file (:func:`lock_name`, in
:data:`LOCK_DIR`) for as long as it runs; the kernel drops the lock when the process ends,
however it ends, so a held lock is what "live" means here (a pid written in the file may have
been reused since). Who holds a lock is read from ``/proc/locks`` without touching it: a probe
that took the lock itself, even for a moment, could make a ``flexarm up`` starting just then
refuse the domain. The run folder's graph record (:data:`RECORD`) adds the robot and the run
folder. No rclpy: files and processes only, so that every client (the CLI and
``flexarm_control.ros.client.init_client``) can look before it joins a domain.
"""
from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path

RECORD = 'graph.json'  # in the run folder: supervisor, domain, node processes, restarts
LOCK_DIR = Path(tempfile.gettempdir()) / 'flexarm-domains'   # <domain id>.lock per graph
DOMAIN_ENV = 'ROS_DOMAIN_ID'


def lock_name(domain_id: int, namespace: str = '') -> str:
    """The lock file name of ``domain_id`` and the arm in ``namespace`` (the '/' of a nested
    namespace as '.', which no name part holds, so the name stays one file of LOCK_DIR)."""
    ns = namespace.strip('/').replace('/', '.')
    return f'{domain_id}-{ns}.lock' if ns else f'{domain_id}.lock'


def lock_text(pid: int, site: Path | None) -> str:
    """What a graph's lock file holds: its supervisor's pid, then the site folder it runs in
    ('' for none), so that a client in another shell finds the graph's site as well as its
    domain (the run record lies in that site)."""
    return f'{pid}\n{site or ""}'


def lock_site(path: Path) -> str:
    """The site folder written in a lock file ('' for none, or unreadable)."""
    try:
        lines = path.read_text(encoding='utf-8', errors='replace').split('\n')
    except OSError:
        return ''
    return lines[1].strip() if len(lines) > 1 else ''


def parse_lock_name(name: str) -> tuple[int, str] | None:
    """(domain id, namespace) of a :func:`lock_name`; None for another file name."""
    if not name.endswith('.lock'):
        return None
    domain, _, ns = name.removesuffix('.lock').partition('-')
    return (int(domain), ns.replace('.', '/')) if domain.isdigit() else None


PROC_LOCKS = Path('/proc/locks')
FileKey = tuple[int, int, int]      # (device major, minor, inode): a file as /proc/locks names it


def lock_holders(proc_locks: str) -> list[tuple[FileKey, int]]:
    """(file, holder pid) of every FLOCK in ``/proc/locks``' text: a pair per holder (a shared
    lock has several), none for a process waiting for a lock."""
    holders = []
    for line in proc_locks.splitlines():
        fields = line.split()
        if len(fields) < 6 or fields[1] != 'FLOCK':
            continue            # another kind, or '->': a process waiting for the lock
        try:
            major, minor, inode = fields[5].split(':')
            holders.append(((int(major, 16), int(minor, 16), int(inode)), int(fields[4])))
        except ValueError:
            continue
    return holders


def held_locks(proc_locks: Path = PROC_LOCKS) -> list[tuple[FileKey, int]]:
    """:func:`lock_holders` of this machine now (none if ``proc_locks`` cannot be read):
    psutil has no view of flocks."""
    try:
        return lock_holders(proc_locks.read_text())
    except OSError:
        return []


def file_key(info: os.stat_result) -> FileKey:
    """The :data:`FileKey` of a file's ``stat``."""
    return os.major(info.st_dev), os.minor(info.st_dev), info.st_ino


def lock_holder(path: Path, holders: Mapping[FileKey, int]) -> int | None:
    """The pid holding an flock on ``path`` (of :func:`lock_holders`), None if none does."""
    try:
        return holders.get(file_key(path.stat()))
    except OSError:
        return None


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
    site: str = ''          # the site folder it runs in ('' for none)

    def as_dict(self) -> dict[str, object]:
        return asdict(self) | {'nodes': list(self.nodes)}


def running_graphs(lock_dir: Path, runs_dir: Path, proc_locks: Path = PROC_LOCKS
                   ) -> list[RunningGraph]:
    """Every graph whose supervisor holds its lock in ``lock_dir``, by domain and namespace,
    with what its record under ``runs_dir`` says."""
    holders = dict(held_locks(proc_locks))
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
        site = lock_site(path)
        record = records.get((pid, *key))
        if record is None and site:          # its record lies in its site's runs/
            record = _records(Path(site) / 'runs').get((pid, *key))
        record = record or {}
        graphs.append(RunningGraph(
            key[0], key[1], pid, started, str(record.get('robot', '?')),
            str(record.get('run_dir', '')), tuple(record.get('nodes', {})), site))
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


class SeveralGraphs(LookupError):
    """Several graphs run on this machine and nothing says which one a client means."""


def this_machines_graph(namespace: str, env: Mapping[str, str], lock_dir: Path = LOCK_DIR,
                        runs_dir: Path | None = None) -> RunningGraph | None:
    """The graph a client of the arm in ``namespace`` means when it names no domain: None with
    an exported ``ROS_DOMAIN_ID`` (rcl's) or no graph running here, else the one graph of that
    arm on this machine; :class:`SeveralGraphs` when several could be meant."""
    if env.get(DOMAIN_ENV, '').strip():
        return None
    if runs_dir is None:
        from flexarm_core.paths import RUNS_DIR
        runs_dir = RUNS_DIR
    graphs = running_graphs(lock_dir, runs_dir)
    ns = namespace.strip('/')
    mine = [g for g in graphs if g.namespace == ns] or graphs
    domains = sorted({g.domain_id for g in mine})
    if len(domains) > 1:
        raise SeveralGraphs(
            f'{len(mine)} flexarm graphs run on this machine, in ROS domains '
            f'{", ".join(map(str, domains))}: pass --domain-id N (or export '
            f'{DOMAIN_ENV}=N) to say which (flexarm ps lists them)')
    return mine[0] if mine else None


def graph_domain(namespace: str, env: Mapping[str, str], lock_dir: Path = LOCK_DIR,
                 runs_dir: Path | None = None) -> tuple[int | None, str]:
    """The domain a client of the arm in ``namespace`` joins when it was given none, and
    what to tell its user: the exported ``ROS_DOMAIN_ID`` (None: rcl reads it), else the one
    graph of that arm running on this machine (a second shell finds the graph ``flexarm up``
    started in the first free domain), else rcl's default (None). :class:`SeveralGraphs`
    when several graphs could be meant."""
    graph = this_machines_graph(namespace, env, lock_dir, runs_dir)
    if graph is None:
        return None, ''
    return graph.domain_id, (
        f'using the flexarm graph of this machine in {DOMAIN_ENV}={graph.domain_id}'
        f' (robot {graph.robot}, started by flexarm up, supervisor pid '
        f'{graph.supervisor_pid}' + (f', site {graph.site}' if graph.site else '') + ')')
