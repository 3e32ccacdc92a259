"""Faults as a user meets them: nodes killed mid-goal, a second graph, `flexarm up` stopped.

Every fault really happens, end to end: `flexarm up` and the `flexarm move`/`collect` commands
run as subprocesses (this process holds no DDS participant), each graph in a ROS domain of its
own, and nodes are killed with SIGKILL. Three graphs, one fault after another on each:

* simulator graph: compensator killed mid-goal, learner killed mid-collection, vision killed
  mid-goal (CLOSED_LOOP, which measures) and mid-collection, a second `flexarm up` in the same
  domain, a peer on another host (a network namespace) commanding the arm, a goal abandoned by
  its client (killed while the arm moves), simulator killed mid-goal, then SIGTERM of `flexarm
  up` (idle);
* bridge graph (fake controller + bridge): a second controller client on the controller's TCP
  port, a keyless peer replaying a recorded handshake against a keyed controller, bridge
  killed mid-goal, then SIGTERM of `flexarm up` mid-goal;
* simulator graph: SIGKILL of `flexarm up` mid-goal.

Per scenario: detected [s] from the fault until the user learns of it (the command whose
server or controller died exits non-zero; a node whose death leaves the goal running: `flexarm
up` reports it; the second graph or controller client: it is refused; `flexarm up` signalled:
every process of the graph is gone); recovered [s] from the fault until a fresh goal (or
collection) succeeds again, or the running one succeeded; samples lost (reported collected by
the client, less the poses the learner logged as skipped, minus the complete records on disk,
plus torn records); orphans (processes carrying the graph's environment marker that outlive
what started them, after a bounded wait; at the end, every process of the graph or its
commands still there once `flexarm up` has stopped); stale shm: the /dev/shm files this run's
processes created that are still there once the graph and its commands are down and that
no process uses, counted before anything is cleaned (:class:`ShmLedger`: every file a process
of the graph or of its commands maps, holds open or locks, sampled every second and before each
SIGKILL this harness sends, less the files that were there before the graph started), then
removed; a file is counted for the scenario that killed its owner (or the second graph that
made it), the rest for the graph's teardown (the scenario that stops `flexarm up`, else the
graph's last row). A command still running when its scenario is done is ended as a user would
(SIGTERM, then SIGKILL).

Lifetimes: every process this harness starts gets SIGTERM when it dies, also by SIGKILL
(``PR_SET_PDEATHSIG``, armed in the child before exec by the main thread, the one that lives as
long as the run), and SIGTERM to this harness stops its graphs and commands and removes the
shared memory they left, as the end of a run does.

    python tests/endurance/faults.py [--only SCENARIOS] [--json]

``--only`` runs some of the scenarios, by key (:data:`KEYS`: ``compensator``, ``learner``,
``vision_goal``, ``vision_collection``, ``second_up``, ``remote``, ``abandoned``, ``sim``,
``sigterm_idle``; ``second_client``, ``replay``, ``bridge``, ``sigterm_goal``;
``sigkill_goal``), each in its graph; a graph
none of them needs is not started. A smoke run of the harness: ``--only sigterm_idle``. A new
scenario is a function ``(graph, row)`` and an entry of :data:`PLANS`.

JSON (last line): ``lost_samples``, ``orphans``, ``stale_shm`` (sums), ``max_detect_s`` (over
the scenarios that detected; ``undetected`` names the others), ``remote_moves`` (1 if the remote
peer moved the arm), ``replay_accepted`` (handshakes the keyed controller accepted from the
replayer), ``abandoned_goal_s`` (from the client's SIGKILL until the compensator cancelled its
goal; each None when its scenario did not run or could not, e.g. ``remote`` without network
namespaces), ``seconds`` and ``scenarios``.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from types import FrameType
from typing import IO

import psutil

from flexarm_bridge import controller_protocol as proto
from flexarm_bridge.link_auth import load_key, make_key
from flexarm_bringup.domains import reserved
from flexarm_bringup.launcher import NodeProcess, load_rehearsal, ros_env, stop_all
from flexarm_core.dds_shm import owned_shm, remove_shm_of_dead, shm_in_use
from flexarm_core.graph_locks import file_key, held_locks
from flexarm_core.params import load_config
from flexarm_core.parent_death import terminate_with_parent
from flexarm_core.paths import RUNS_DIR, repo_path
from flexarm_core.processes import command_line, descendants, environments, mapped_files
from flexarm_deflection.dataset import load_dataset
from flexarm_test_support.link_attacks import replay_accepted
from flexarm_test_support.remote_peer import remote_attack, unavailable

FLEXARM = str(Path(sys.executable).with_name('flexarm'))
MARKER = 'FLEXARM_FAULT_RUN'
SHM = Path('/dev/shm')
RTF = 3.0              # simulator real-time factor: moves of ~1 s wall, collections ~2 s/sample
# Long-motion targets of the README (CLI units: mm, mm, deg); goals alternate between them.
POSES = ((1450.0, -150.0, -45.0), (1000.0, -500.0, -100.0))
READY_S = 120.0        # [s] bounds of every wait
MOVE_S = 120.0
DETECT_S = 60.0
RECOVER_S = 90.0
TEARDOWN_S = 20.0
SETTLE_S = 5.0         # for processes of a fault to go before orphans are counted
STOP_S = 15.0          # for a command to end on SIGTERM (a goal cancelled, a graph stopped)
SAMPLE_S = 1.0         # [s] between two samples of the shared memory the graph's processes use
KILLED_SAMPLES = 10    # on disk before the learner is killed
VISION_SAMPLES = 3     # on disk before the vision node is killed mid-collection


class ScenarioError(RuntimeError):
    """A scenario could not inject its fault (the precondition did not happen in time)."""


@dataclass
class Row:
    scenario: str
    detected_s: float | None = None
    recovered_s: float | None = None
    lost_samples: int = 0
    orphans: int = 0
    stale_shm: int = 0
    detects: bool = True         # a fault the user must learn of (else an attack refused)
    remote_moves: int | None = None     # the arm moved for a peer on another host (0/1)
    replay_accepted: int | None = None  # replayed or reflected handshakes a controller took
    abandoned_goal_s: float | None = None   # from its client's death until it was cancelled
    note: str = ''

    def add(self, text: str) -> None:
        """Append ``text`` to the note."""
        self.note = f'{self.note}; {text}' if self.note else text


# --- processes ------------------------------------------------------------------------------
def markers() -> dict[int, str]:
    """Live (not zombie) processes whose environment carries a :data:`MARKER`: its value."""
    return {pid: env[MARKER] for pid, env in environments().items() if env.get(MARKER)}


def marked(marker: str, family: bool = False) -> set[int]:
    """Live processes carrying ``marker`` (``family``: or a marker ``<marker>-...``: the
    graph's commands and second graph)."""
    return {pid for pid, value in markers().items()
            if value == marker or family and value.startswith(f'{marker}-')}


def node_pid(marker: str, name: str) -> int:
    """PID of the running node ``name`` of the marked graph."""
    for pid in marked(marker):
        if f'__node:={name}' in command_line(pid):
            return pid
    raise ScenarioError(f'no running {name} process')


def wait_until(condition: Callable[[], bool], timeout: float, poll: float = 0.05) -> float | None:
    """Monotonic time at which ``condition()`` held, or None after ``timeout``."""
    deadline = time.monotonic() + timeout
    while True:
        if condition():
            return time.monotonic()
        if time.monotonic() > deadline:
            return None
        time.sleep(poll)


# --- shared memory --------------------------------------------------------------------------
def shm_inodes() -> dict[str, int]:
    """Files of /dev/shm and their inodes."""
    found = {}
    for path in SHM.iterdir():
        try:
            found[path.name] = path.stat().st_ino
        except OSError:
            continue
    return found


def _flocked(pid: int) -> set[int]:
    """Inodes of the /dev/shm files ``pid`` holds an flock on."""
    device = file_key(SHM.stat())[:2]
    return {key[2] for key, holder in held_locks() if holder == pid and key[:2] == device}


def _opened(pid: int) -> set[str]:
    """Names of the /dev/shm files ``pid`` holds open (none once it is gone)."""
    try:
        files = psutil.Process(pid).open_files()
    except psutil.Error:
        return set()
    return {Path(f.path).name for f in files if f.path.startswith(f'{SHM}/')}


def used_shm(pid: int, files: dict[str, int]) -> dict[str, int]:
    """The /dev/shm files (of ``files``: name -> inode) that ``pid`` maps, holds open or
    locks, with the mutex of every Fast DDS port it maps (nobody keeps that one open)."""
    inodes = _flocked(pid)
    names = {Path(path).name for path in mapped_files(SHM, pid)} | _opened(pid)
    used = {name: inode for name, inode in files.items() if name in names or inode in inodes}
    for name in list(used):
        mutex = f'sem.{name}_mutex'
        if name.startswith('fastrtps_port') and mutex in files:
            used[mutex] = files[mutex]
    return used


@dataclass
class ShmLedger:
    """The /dev/shm files the processes of one graph (a marker family) created: each file one of
    them uses (:func:`used_shm`) that was not there (same name and inode) before; with the marker
    of the process that owns it (:func:`~flexarm_core.dds_shm.owned_shm`: the
    files its death by a signal leaves), else of the first that used it.

    Sampled every :data:`SAMPLE_S` and before every SIGKILL of the harness: a file is missed
    only if its process made it and died on its own within a second.
    """

    family: str
    before: dict[str, int] = field(default_factory=shm_inodes)
    files: dict[str, tuple[int, str]] = field(default_factory=dict)   # name: inode, marker
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def sample(self, pids: Iterable[int] | None = None) -> None:
        """Note the files of ``pids`` (default: every process of the family)."""
        found = markers()
        now = shm_inodes()
        with self._lock:
            for pid in found if pids is None else pids:
                marker = found.get(pid)
                if marker is None or not (marker == self.family
                                          or marker.startswith(f'{self.family}-')):
                    continue
                owned = {path.name for path in owned_shm(pid)}
                for name, inode in used_shm(pid, now).items():
                    if self.before.get(name) == inode:
                        continue
                    if name in owned or name not in self.files:
                        self.files[name] = (inode, marker)

    def left(self) -> dict[str, str]:
        """The files still there (same inode) that no live process uses (a Fast DDS port is
        one of a pool shared over time by every domain), with their markers."""
        now, used = shm_inodes(), shm_in_use()
        with self._lock:
            return {name: marker for name, (inode, marker) in self.files.items()
                    if now.get(name) == inode and str(SHM / name) not in used}


class Sampler:
    """Samples a :class:`ShmLedger` every :data:`SAMPLE_S` in a thread, until stopped."""

    def __init__(self, ledger: ShmLedger) -> None:
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, args=(ledger,), daemon=True)
        self._thread.start()

    def _run(self, ledger: ShmLedger) -> None:
        while not self._stop.wait(SAMPLE_S):
            ledger.sample()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


# --- commands -------------------------------------------------------------------------------
class Command:
    """A ``flexarm`` subprocess; its merged output lines with their arrival times. It gets
    SIGTERM when this harness ends, however (started by the main thread)."""

    def __init__(self, args: Iterable[str], env: dict[str, str],
                 ledger: ShmLedger | None = None) -> None:
        self.started = time.monotonic()
        self.ledger = ledger
        self.process = subprocess.Popen(
            [FLEXARM, *args], env={**env, 'PYTHONUNBUFFERED': '1'}, stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, errors='replace',
            start_new_session=True, preexec_fn=terminate_with_parent)
        self.lines: list[tuple[float, str]] = []
        self._ended = False
        self._cond = threading.Condition()
        threading.Thread(target=self._read, args=(self.process.stdout,), daemon=True).start()

    def _read(self, stream: IO[str]) -> None:
        for line in stream:            # universal newlines: a progress bar's \r ends a line
            with self._cond:
                self.lines.append((time.monotonic(), line.rstrip('\n')))
                self._cond.notify_all()
        with self._cond:
            self._ended = True
            self._cond.notify_all()

    def wait_line(self, pattern: str, timeout: float, since: float = 0.0) -> float | None:
        """Arrival time of the first line since ``since`` matching ``pattern``, or None."""
        regex, deadline = re.compile(pattern), time.monotonic() + timeout
        with self._cond:
            while True:
                for stamp, line in self.lines:
                    if stamp >= since and regex.search(line):
                        return stamp
                remaining = deadline - time.monotonic()
                if remaining <= 0 or self._ended:
                    return None
                self._cond.wait(min(remaining, 0.2))

    def wait_exit(self, timeout: float) -> float | None:
        """Time the process exited, or None if it still runs after ``timeout``."""
        return wait_until(lambda: self.process.poll() is not None, timeout, poll=0.02)

    @property
    def text(self) -> str:
        with self._cond:
            return '\n'.join(line for _, line in self.lines)

    def last_line(self) -> str:
        lines = [line for line in self.text.splitlines() if line.strip()]
        return lines[-1].strip() if lines else ''

    def stop(self) -> None:
        """End it if it still runs, as a user would: SIGTERM (a goal is cancelled, a graph
        stopped), SIGKILL after ``STOP_S`` (its shared memory noted first); reap it."""
        if self.process.poll() is None:
            self.process.terminate()
            if self.wait_exit(STOP_S) is None:
                if self.ledger is not None:
                    self.ledger.sample(descendants([self.process.pid]))
                self.process.kill()
        try:
            self.process.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            pass


class Graph:
    """One ``flexarm up`` with its marker, the shared memory its processes create, and its
    faults. Its commands carry ``<marker>-client``, a second graph ``<marker>-second``."""

    def __init__(self, label: str, domain: int, robot: str, tag: str) -> None:
        self.label, self.domain, self.robot = label, domain, robot
        self.marker = f'{tag}-{label}'
        self.env = dict(os.environ)
        self.ledger = ShmLedger(self.marker)
        self.datasets: list[Path] = []
        self.rows: list[Row] = []
        self.owned: list[tuple[Row, set[str]]] = []   # files of each killed node
        self.made_by: dict[str, Row] = {}     # marker of processes a scenario started: its row
        self.at: tuple[float, float, float] | None = None   # target of the last goal
        # a bridge graph drives the rehearsal program (the simulated arm behind the
        # controller protocol, on the wall clock), started first as a site's controller is
        self.rehearsal = (Command(['rehearse', '--domain-id', str(domain)],
                                  {**self.env, MARKER: f'{self.marker}-rehearsal'}, self.ledger)
                          if robot == 'bridge' else None)
        self.up = self.start_up()
        self._sampler = Sampler(self.ledger)

    def start_up(self, marker: str | None = None) -> Command:
        env = {**self.env, MARKER: marker or self.marker}
        return Command(['up', '--domain-id', str(self.domain), '--robot', self.robot,
                        '--rtf', str(RTF), '--timeout', str(READY_S),
                        '--name', f'faults-{marker or self.marker}'], env, self.ledger)

    def wait_ready(self) -> None:
        if self.up.wait_line(r'graph ready in', READY_S) is None:
            raise RuntimeError(f'{self.label} graph not ready: {self.up.last_line()}')

    def command(self, *args: str) -> Command:
        return Command([*args, '--domain-id', str(self.domain)],
                       {**self.env, MARKER: f'{self.marker}-client'}, self.ledger)

    def run(self, *args: str, timeout: float = MOVE_S) -> Command:
        """Run a command to its end (killed after ``timeout``)."""
        command = self.command(*args)
        try:
            command.wait_exit(timeout)
        finally:
            command.stop()
        return command

    def kill(self, pids: Iterable[int]) -> None:
        """SIGKILL ``pids`` (processes of the graph), their shared memory noted first."""
        pids = list(pids)
        self.ledger.sample(pids)
        for pid in pids:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass

    def kill_node(self, name: str, row: Row) -> float:
        """SIGKILL the node ``name``; the time of the kill."""
        pid = node_pid(self.marker, name)
        self.owned.append((row, {path.name for path in owned_shm(pid)}))
        self.kill([pid])
        return time.monotonic()

    def reported_death(self, name: str, since: float) -> float | None:
        """Time ``flexarm up`` reported the death of ``name`` (after ``since``)."""
        return self.up.wait_line(rf'node {name} exited with code', DETECT_S, since)

    def dataset(self, purpose: str) -> tuple[str, Path]:
        name = f'faults-{self.marker}-{purpose}'
        path = repo_path(load_config('learner.yaml', node_name='flexarm_learner')[
            'data_directory']) / f'{name}.jsonl'
        self.datasets.append(path)
        return name, path

    def long_goal(self, mode: str) -> Command:
        """A goal to the other target (after moving to the first one if needed), once the
        arm moves."""
        if self.at is None:
            self.goal_ok('rigid')
        self.at = POSES[1] if self.at == POSES[0] else POSES[0]
        client = self.command('move', *map(str, self.at), '--mode', mode,
                              '--timeout', str(MOVE_S))
        if client.wait_line(r'\] moving', MOVE_S) is None:
            client.stop()
            raise ScenarioError(f'the goal did not start moving: {client.last_line()}')
        return client

    def goal_ok(self, mode: str) -> bool:
        """Whether a goal to the last target (a short move, or none) succeeds."""
        self.at = self.at or POSES[0]
        return self.run('move', *map(str, self.at), '--mode', mode,
                        '--timeout', str(MOVE_S)).process.returncode == 0

    def until_ok(self, attempt: Callable[[], bool], since: float) -> float | None:
        """Seconds from ``since`` until ``attempt()`` succeeds (retried), or None."""
        while time.monotonic() - since < RECOVER_S:
            if attempt():
                return time.monotonic() - since
            time.sleep(1.0)
        return None

    def orphans(self, root: int) -> int:
        """Marked processes outside ``root``'s tree, once the bounded wait for them is over."""
        left: set[int] = set()

        def none_left() -> bool:
            nonlocal left
            left = marked(self.marker) - descendants([root])
            return not left
        wait_until(none_left, SETTLE_S)
        return len(left)

    def stop(self, sig: int, row: Row) -> None:
        """Signal ``flexarm up``; detection and orphans of the whole graph."""
        if sig == signal.SIGKILL:
            self.ledger.sample()
        os.kill(self.up.process.pid, sig)
        signalled = time.monotonic()
        gone = wait_until(lambda: not marked(self.marker), TEARDOWN_S)
        row.detected_s = None if gone is None else gone - signalled
        left = marked(self.marker)
        row.orphans = len(left)
        for _, line in self.up.lines:
            if line.startswith('stopped: '):
                row.add(line)
        for pid in left:
            row.add(f'left: {pid} {" ".join(command_line(pid))[:80]!r}')

    def close(self, teardown: Row) -> None:
        """Stop everything left of this graph and its commands (after it was measured): its
        processes still there once ``flexarm up`` has stopped are ``teardown``'s orphans; then
        the shared memory it left (:meth:`account`)."""
        try:
            self.up.stop()
            if self.rehearsal is not None:
                self.rehearsal.stop()
            wait_until(lambda: not marked(self.marker, family=True), SETTLE_S)
            left = marked(self.marker, family=True)
            teardown.orphans += len(left)
            if left:
                teardown.add(f'{len(left)} process(es) left at the end, killed')
            self.kill(left)
            wait_until(lambda: not marked(self.marker, family=True), SETTLE_S)
        finally:
            self._sampler.stop()
            self.account(teardown)
            for path in self.datasets:
                path.unlink(missing_ok=True)

    def account(self, teardown: Row) -> None:
        """Count the shared memory the graph's processes left, per scenario (the one that
        killed its owner, the second graph that made it, else ``teardown``), then remove it."""
        left = self.ledger.left()
        rest = set(left)
        for row, files in self.owned:
            row.stale_shm += len(rest & files)
            rest -= files
        for name in list(rest):
            if left[name] in self.made_by:
                self.made_by[left[name]].stale_shm += 1
                rest.remove(name)
        teardown.stale_shm += len(rest)
        if rest:
            clients = sum(left[name] == f'{self.marker}-client' for name in rest)
            teardown.add(f'stale: {sorted(rest)[:6]} ({clients} of the commands\' processes)')
        remove_shm_of_dead([SHM / name for name in left])


# --- scenarios ------------------------------------------------------------------------------
def server_killed_mid_goal(graph: Graph, node: str, mode: str, row: Row) -> None:
    """Kill the goal's server or controller while the arm moves; a fresh goal recovers."""
    client = graph.long_goal(mode)
    try:
        killed = graph.kill_node(node, row)
        exited = client.wait_exit(DETECT_S)
    finally:
        client.stop()
    row.add(client.last_line())
    if exited is not None and client.process.returncode != 0:
        row.detected_s = exited - killed
    if graph.up.wait_line(rf'node {node} restarted', SETTLE_S, killed) is None:
        row.add(f'{node} not restarted')
    else:
        row.recovered_s = graph.until_ok(lambda: graph.goal_ok(mode), killed)
    row.orphans = graph.orphans(graph.up.process.pid)


def vision_killed_mid_goal(graph: Graph, row: Row) -> None:
    """Kill the vision node while a CLOSED_LOOP goal moves: the goal still has to end well."""
    client = graph.long_goal('closed_loop')
    try:
        killed = graph.kill_node('flexarm_vision', row)
        reported = graph.reported_death('flexarm_vision', killed)
        exited = client.wait_exit(MOVE_S)
    finally:
        client.stop()
    row.detected_s = None if reported is None else reported - killed
    row.add(f'the goal: {client.last_line()}')
    if exited is not None and client.process.returncode == 0:
        row.recovered_s = exited - killed
    else:
        row.recovered_s = graph.until_ok(lambda: graph.goal_ok('closed_loop'), killed)
    row.orphans = graph.orphans(graph.up.process.pid)


def samples_on_disk(path: Path) -> int:
    try:
        return len(load_dataset(path))
    except (OSError, ValueError):
        return 0


def wait_samples(path: Path, count: int, timeout: float) -> float | None:
    return wait_until(lambda: samples_on_disk(path) >= count, timeout, poll=0.1)


def lost_samples(path: Path, claimed: int) -> tuple[int, str]:
    """Claimed samples missing from the dataset plus its torn records; and a description."""
    data = load_dataset(path)
    lost = max(0, claimed - len(data)) + data.skipped
    return lost, f'{claimed} reported, {len(data)} on disk, {data.skipped} torn'


def collection_log(graph: Graph, path: Path) -> str:
    """The learner's log since its last collection into ``path`` began."""
    log = (RUNS_DIR / f'faults-{graph.marker}' / 'flexarm_learner.log').read_text(
        errors='replace')
    return log[log.rfind(f'into {path}'):]


def skipped_poses(graph: Graph, path: Path) -> int:
    """Poses the learner logged as skipped (its last attempt failed) collecting into ``path``."""
    retries = load_config('learner.yaml', node_name='flexarm_learner')['measurement_retries']
    return collection_log(graph, path).count(f'(attempt {1 + retries})')


def learner_killed_mid_collection(graph: Graph, row: Row) -> None:
    """Kill the learner after some samples are on disk; none the client was told of may be
    missing, and a fresh collection into the same dataset recovers."""
    name, path = graph.dataset('learner')
    client = graph.command('collect', '40', '--dataset', name)
    try:
        if wait_samples(path, KILLED_SAMPLES, READY_S) is None:
            raise ScenarioError(f'fewer than {KILLED_SAMPLES} samples: {client.last_line()}')
        killed = graph.kill_node('flexarm_learner', row)
        exited = client.wait_exit(DETECT_S)
    finally:
        client.stop()
    if exited is not None and client.process.returncode != 0:
        row.detected_s = exited - killed
    progress = re.findall(r'(\d+)/\d+ \[', client.text)
    claimed = (int(progress[-1]) if progress else 0) - skipped_poses(graph, path)
    row.lost_samples, counts = lost_samples(path, claimed)
    row.add(f'{client.last_line()}; {counts}')

    def collect_again() -> bool:
        again = graph.run('collect', '2', '--dataset', name, timeout=RECOVER_S)
        done = re.search(r'(\d+) samples in', again.text)
        if again.process.returncode != 0 or done is None:
            return False
        row.lost_samples += max(0, int(done[1]) - samples_on_disk(path))
        return True
    row.recovered_s = graph.until_ok(collect_again, killed)
    row.orphans = graph.orphans(graph.up.process.pid)


def vision_killed_mid_collection(graph: Graph, row: Row) -> None:
    """Kill the vision node during a collection: it must go on and lose nothing."""
    name, path = graph.dataset('vision')
    client = graph.command('collect', '8', '--dataset', name)
    try:
        if wait_samples(path, VISION_SAMPLES, READY_S) is None:
            raise ScenarioError(f'fewer than {VISION_SAMPLES} samples: {client.last_line()}')
        before = samples_on_disk(path)       # just stored: the arm moves on to the next pose
        killed = graph.kill_node('flexarm_vision', row)
        reported = graph.reported_death('flexarm_vision', killed)
        measured = wait_samples(path, before + 1, RECOVER_S)
        client.wait_exit(RECOVER_S)
    finally:
        client.stop()
    row.detected_s = None if reported is None else reported - killed
    row.recovered_s = None if measured is None else measured - killed
    row.orphans = graph.orphans(graph.up.process.pid)
    done = re.search(r'(\d+) collected, \d+ skipped', client.text)
    if client.process.returncode != 0 or done is None:
        row.add(f'the collection failed: {client.last_line()}')
        return
    row.lost_samples, counts = lost_samples(path, int(done[1]))
    failed = collection_log(graph, path).count('no valid settled tip pose')
    row.add(f'{client.last_line()}; {counts}; {failed} measurement attempts failed')


def second_graph(graph: Graph, row: Row) -> None:
    """A second ``flexarm up`` in the domain: refused, nothing of it left, the first serves
    (what shared memory it left is counted with the graph's, :meth:`Graph.account`)."""
    marker = f'{graph.marker}-second'
    graph.made_by[marker] = row
    second = graph.start_up(marker)
    try:
        started_graph = second.wait_line(r'graph ready in', DETECT_S)   # None once it exits
        exited = second.wait_exit(SETTLE_S)
    finally:
        second.stop()
    if started_graph is None and exited is not None and second.process.returncode != 0:
        row.detected_s = exited - second.started
        row.add(second.last_line()[:120])
    else:
        row.add('NOT refused: ' + ' | '.join(line[:70] for _, line in second.lines[:2]))
    wait_until(lambda: not marked(marker), SETTLE_S)
    row.orphans = len(marked(marker))
    graph.kill(marked(marker))
    row.recovered_s = graph.until_ok(lambda: graph.goal_ok('rigid'), second.started)
    died = [line for stamp, line in graph.up.lines
            if stamp >= second.started and 'exited with code' in line]
    if died:
        row.add(f'first graph: {died}')


def second_controller_client(graph: Graph, row: Row) -> None:
    """A second PC on the controller's port while the bridge is connected: refused at once."""
    port = load_config('bridge.yaml')['port']
    decoder, refused, closed = proto.Decoder(), None, None
    start = time.monotonic()
    with socket.create_connection(('127.0.0.1', port), timeout=5.0) as conn:
        conn.settimeout(0.2)
        while closed is None and time.monotonic() - start < DETECT_S:
            try:
                data = conn.recv(4096)
            except TimeoutError:
                continue
            if not data:
                closed = time.monotonic()
                break
            frames, _ = decoder.feed(data)
            types = [proto.TYPE_NAMES.get(f.type, str(f.type)) for f in frames]
            if any(f.type == proto.ERROR and f.fields['code'] == proto.E_BUSY for f in frames):
                refused = refused or time.monotonic()
            elif frames:
                row.add(f'got {types} instead of a refusal')
                break
    row.detected_s = None if refused is None else refused - start
    if refused is not None:
        row.add('ERROR code 5 (busy), ' + (
            f'closed after {closed - start:.3f} s' if closed else 'NOT closed'))


def remote_peer(graph: Graph, row: Row) -> None:
    """A peer on another host (a network namespace joined by a veth pair) names this one in
    ROS_STATIC_PEERS and publishes joint commands: it must see no node and move nothing."""
    row.detects = False
    reason = unavailable()
    if reason:
        raise ScenarioError(f'not run: {reason}')
    attack = remote_attack(graph.domain)
    row.remote_moves = int(bool(attack['moved']))
    row.add(f"the peer saw {len(attack['nodes_seen'])} node(s), published "
            f"{attack['commands_published']} command(s); the arm "
            f"{'MOVED' if attack['moved'] else 'did not move'}")


def abandoned_goal(graph: Graph, row: Row) -> None:
    """A raw client sends a long CLOSED_LOOP goal and is killed while the arm moves: the
    compensator must cancel the goal (flexarm_test_support.abandoned_goal, in a process of its
    own)."""
    done = subprocess.run(
        [sys.executable, '-m', 'flexarm_test_support.abandoned_goal', '--domain-id',
         str(graph.domain)], env={**graph.env, MARKER: f'{graph.marker}-client'},
        capture_output=True, text=True, timeout=MOVE_S, stdin=subprocess.DEVNULL,
        preexec_fn=terminate_with_parent)
    if done.returncode != 0:
        raise ScenarioError(f'the abandoning client failed: {done.stderr.strip()[-500:]}')
    row.abandoned_goal_s = json.loads(done.stdout.strip().splitlines()[-1])['abandoned_goal_s']
    row.detected_s = row.abandoned_goal_s
    row.add(f'goal cancelled {row.abandoned_goal_s:.2f} s after its client died')


def replayed_handshakes(graph: Graph, row: Row) -> None:
    """A keyless peer replays a genuine session recorded on the wire (and reflects the
    controller's own frames) against a controller with a site key: a fake controller of its
    own on a free port, since the graph's holds its bridge's link
    (flexarm_test_support.link_attacks)."""
    row.detects = False
    run_dir = RUNS_DIR / f'faults-{graph.marker}' / 'replay'
    run_dir.mkdir(parents=True, exist_ok=True)
    key = make_key(run_dir / 'site.key')
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        port = probe.getsockname()[1]
    spec = next(s for s in load_rehearsal() if s.name == 'flexarm_fake_controller')
    controller = NodeProcess(
        spec, {**ros_env(graph.domain, run_dir / 'ros_log'), MARKER: f'{graph.marker}-client'},
        run_dir / 'fake_controller.log', {'port': port, 'link_key_file': str(key)})
    controller.start()
    try:
        if wait_until(lambda: 'controller protocol v' in controller.log_tail(50),
                      READY_S) is None:
            raise ScenarioError(f'the keyed controller did not listen: {controller.log_tail()}')
        row.replay_accepted = replay_accepted(port, load_key(key))
        row.add(f'{row.replay_accepted} replayed handshake(s) accepted')
    finally:
        stop_all([controller])


def stop_graph(graph: Graph, sig: int, mid_goal: bool, row: Row) -> None:
    """Signal ``flexarm up`` (mid-goal or idle); every process of the graph must go."""
    client = graph.long_goal('rigid') if mid_goal else None
    try:
        graph.stop(sig, row)
    finally:
        if client is not None:
            client.wait_exit(DETECT_S)       # it learns that its server is gone
            client.stop()
            row.add(f'the goal: {client.last_line()}')


# --- the run --------------------------------------------------------------------------------
@dataclass(frozen=True)
class Scenario:
    """One fault: ``run(graph, row)`` injects it and fills the row (a ScenarioError, OSError,
    RuntimeError or ValueError ends up in the row's note)."""

    key: str                                # for --only
    name: str                               # its row
    run: Callable[[Graph, Row], None]
    stops_graph: bool = False               # it stops `flexarm up`: its row is the teardown's


@dataclass(frozen=True)
class Plan:
    """A graph (``robot`` entry of graph.yaml) and its scenarios, in the order they run."""

    label: str
    robot: str
    scenarios: tuple[Scenario, ...]


PLANS = (
    Plan('sim', 'sim', (
        Scenario('compensator', 'compensator killed mid-goal',
                 lambda g, r: server_killed_mid_goal(g, 'flexarm_compensator', 'rigid', r)),
        Scenario('learner', 'learner killed mid-collection', learner_killed_mid_collection),
        Scenario('vision_goal', 'vision killed mid-goal (closed loop)', vision_killed_mid_goal),
        Scenario('vision_collection', 'vision killed mid-collection',
                 vision_killed_mid_collection),
        Scenario('second_up', 'second flexarm up in the domain', second_graph),
        Scenario('remote', 'remote peer commands the arm', remote_peer),
        Scenario('abandoned', 'goal abandoned by its client', abandoned_goal),
        Scenario('sim', 'simulator killed mid-goal',
                 lambda g, r: server_killed_mid_goal(g, 'flexarm_sim', 'rigid', r)),
        Scenario('sigterm_idle', 'SIGTERM of flexarm up (idle)',
                 lambda g, r: stop_graph(g, signal.SIGTERM, False, r), stops_graph=True))),
    Plan('bridge', 'bridge', (
        Scenario('second_client', 'second controller client (TCP)', second_controller_client),
        Scenario('replay', 'replayed controller handshakes', replayed_handshakes),
        Scenario('bridge', 'bridge killed mid-goal',
                 lambda g, r: server_killed_mid_goal(g, 'flexarm_bridge', 'rigid', r)),
        Scenario('sigterm_goal', 'SIGTERM of flexarm up mid-goal (bridge)',
                 lambda g, r: stop_graph(g, signal.SIGTERM, True, r), stops_graph=True))),
    Plan('kill', 'sim', (
        Scenario('sigkill_goal', 'SIGKILL of flexarm up mid-goal',
                 lambda g, r: stop_graph(g, signal.SIGKILL, True, r), stops_graph=True),)),
)
KEYS = tuple(s.key for plan in PLANS for s in plan.scenarios)


def attempt(graph: Graph, scenario: Scenario) -> Row:
    """Run one scenario; an error is reported in its row, not raised."""
    row = Row(scenario.name)
    graph.rows.append(row)
    try:
        scenario.run(graph, row)
    except (ScenarioError, OSError, RuntimeError, ValueError) as exc:
        row.add(f'error: {exc}')
    return row


def run_graph(plan: Plan, tag: str, scenarios: Iterable[Scenario]) -> list[Row]:
    """Start the plan's graph, run ``scenarios`` on it, stop it; their rows. What the graph
    left at its end goes to the row of the scenario that stopped it, else to the last row."""
    with reserved() as domain:
        graph = Graph(plan.label, domain, plan.robot, tag)
        teardown = None
        try:
            graph.wait_ready()
            for scenario in scenarios:
                row = attempt(graph, scenario)
                teardown = row if scenario.stops_graph else teardown
        except (RuntimeError, OSError) as exc:
            graph.rows.append(Row(f'{plan.label} graph', note=f'error: {exc}'))
        finally:
            if teardown is None and not graph.rows:
                graph.rows.append(Row(f'{plan.label} graph', note='interrupted'))
            graph.close(teardown or graph.rows[-1])
    print(f'# {plan.robot} graph in ROS domain {domain}, logs in runs/faults-{graph.marker}/')
    for row in graph.rows:
        print_row(row)
    return graph.rows


def worst(values: Iterable[float | None]) -> float | None:
    """The largest of the values measured (None if no scenario measured one)."""
    return max((v for v in values if v is not None), default=None)


def seconds(value: float | None) -> str:
    return '-' if value is None else f'{value:.2f}'


def print_row(row: Row) -> None:
    print(f'{row.scenario:<40} {seconds(row.detected_s):>10} {seconds(row.recovered_s):>11} '
          f'{row.lost_samples:>4} {row.orphans:>7} {row.stale_shm:>9}  {row.note}', flush=True)


def _terminated(signum: int, frame: FrameType | None) -> None:
    """SIGTERM: end the run as its end does (graphs stopped, their shared memory removed);
    a second one cannot cut that short."""
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise SystemExit(128 + signum)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--only', help=f'comma-separated scenarios of {", ".join(KEYS)} '
                        '(default: every one); a graph with none of them is not started')
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    args = parser.parse_args()
    only = set(args.only.split(',')) if args.only else set(KEYS)
    if only - set(KEYS):
        parser.error(f'unknown scenarios {sorted(only - set(KEYS))}; known: {", ".join(KEYS)}')
    signal.signal(signal.SIGTERM, _terminated)
    started, tag = time.monotonic(), uuid.uuid4().hex[:8]
    print(f'{"scenario":<40} {"detected s":>10} {"recovered s":>11} {"lost":>4} '
          f'{"orphans":>7} {"stale shm":>9}  note', flush=True)
    rows: list[Row] = []
    for plan in PLANS:
        chosen = [s for s in plan.scenarios if s.key in only]
        if chosen:
            rows += run_graph(plan, tag, chosen)
    detected = [r.detected_s for r in rows if r.detects and r.detected_s is not None]
    summary = {'lost_samples': sum(r.lost_samples for r in rows),
               'orphans': sum(r.orphans for r in rows),
               'stale_shm': sum(r.stale_shm for r in rows),
               'max_detect_s': max(detected, default=None),
               'undetected': [r.scenario for r in rows if r.detects and r.detected_s is None],
               **{key: worst([getattr(r, key) for r in rows])
                  for key in ('remote_moves', 'replay_accepted', 'abandoned_goal_s')},
               'seconds': time.monotonic() - started,
               'scenarios': [asdict(r) for r in rows]}
    print(f"{len(rows)} scenarios in {summary['seconds']:.0f} s: lost samples "
          f"{summary['lost_samples']}, orphans {summary['orphans']}, stale shm "
          f"{summary['stale_shm']}, max detection {seconds(summary['max_detect_s'])} s"
          + (f"; undetected: {', '.join(summary['undetected'])}" if summary['undetected']
             else ''))
    if args.json:
        print(json.dumps(summary))


if __name__ == '__main__':
    main()
