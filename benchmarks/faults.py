"""Faults as a user meets them: nodes killed mid-goal, a second graph, `flexarm up` stopped.

Every fault really happens, end to end: `flexarm up` and the `flexarm move`/`collect` commands
run as subprocesses (this process holds no DDS participant), each graph in a ROS domain of its
own, and nodes are killed with SIGKILL. Three graphs, one fault after another on each:

* simulator graph: compensator killed mid-goal, learner killed mid-collection, vision killed
  mid-goal (CLOSED_LOOP, which measures) and mid-collection, a second `flexarm up` in the same
  domain, simulator killed mid-goal, then SIGTERM of `flexarm up` (idle);
* bridge graph (fake controller + bridge): a second controller client on the controller's TCP
  port, bridge killed mid-goal, then SIGTERM of `flexarm up` mid-goal;
* simulator graph: SIGKILL of `flexarm up` mid-goal.

Per scenario: detected [s] from the fault until the user learns of it (the command whose
server or controller died exits non-zero; a node whose death leaves the goal running: `flexarm
up` reports it; the second graph or controller client: it is refused; `flexarm up` signalled:
every process of the graph is gone); recovered [s] from the fault until a fresh goal (or
collection) succeeds again, or the running one succeeded; samples lost (reported collected by
the client, less the poses the learner logged as skipped, minus the complete records on disk,
plus torn records); orphans (processes carrying the graph's environment marker that outlive
what started them, after a bounded wait); stale shm (new /dev/shm files that no live process
maps or holds open once the graph is down; a killed node's own files count for its scenario).

    python benchmarks/faults.py [--only SCENARIOS] [--json]

``--only`` runs some of the scenarios, by key (:data:`KEYS`: ``compensator``, ``learner``,
``vision_goal``, ``vision_collection``, ``second_up``, ``sim``, ``sigterm_idle``;
``second_client``, ``bridge``, ``sigterm_goal``; ``sigkill_goal``), each in its graph; a graph
none of them needs is not started. A smoke run of the harness: ``--only sigterm_idle``.

JSON (last line): ``lost_samples``, ``orphans``, ``stale_shm`` (sums), ``max_detect_s`` (over
the scenarios that detected; ``undetected`` names the others), ``seconds`` and ``scenarios``.
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
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import IO

from flexarm_bridge import controller_protocol as proto
from flexarm_bringup.domains import reserved
from flexarm_control.dataset import load_dataset
from flexarm_control.params import load_config
from flexarm_control.paths import RUNS_DIR, repo_path

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
    note: str = ''

    def add(self, text: str) -> None:
        """Append ``text`` to the note."""
        self.note = f'{self.note}; {text}' if self.note else text


# --- processes ------------------------------------------------------------------------------
def _read(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError:
        return b''


def _stat(pid: int) -> tuple[int, str] | None:
    """(parent pid, state) of a process, or None once it is gone."""
    fields = _read(Path(f'/proc/{pid}/stat')).rsplit(b')', 1)[-1].split()
    return (int(fields[1]), fields[0].decode()) if len(fields) > 1 else None


def _pids() -> list[int]:
    return [int(p.name) for p in Path('/proc').iterdir() if p.name.isdigit()]


def marked(marker: str) -> set[int]:
    """Live (not zombie) processes whose environment carries ``marker``."""
    needle = f'{MARKER}={marker}'.encode()
    found = set()
    for pid in _pids():
        stat = _stat(pid)
        if stat and stat[1] != 'Z' and needle in _read(Path(f'/proc/{pid}/environ')).split(b'\0'):
            found.add(pid)
    return found


def node_pid(marker: str, name: str) -> int:
    """PID of the running node ``name`` of the marked graph."""
    arg = f'__node:={name}'.encode()
    for pid in marked(marker):
        if arg in _read(Path(f'/proc/{pid}/cmdline')).split(b'\0'):
            return pid
    raise ScenarioError(f'no running {name} process')


def descendants(root: int) -> set[int]:
    """``root`` and every process below it."""
    children: dict[int, list[int]] = {}
    for pid in _pids():
        stat = _stat(pid)
        if stat:
            children.setdefault(stat[0], []).append(pid)
    found, todo = set(), [root]
    while todo:
        pid = todo.pop()
        found.add(pid)
        todo += children.get(pid, [])
    return found


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


def _held(pid: int) -> dict[str, int]:
    """/dev/shm files a process holds open, by name, with their inodes."""
    held = {}
    fds = Path(f'/proc/{pid}/fd')
    try:
        links = list(fds.iterdir())
    except OSError:
        return held
    for fd in links:
        try:
            target = os.readlink(fd)
            if target.startswith(f'{SHM}/'):
                held[Path(target.removesuffix(' (deleted)')).name] = fd.stat().st_ino
        except OSError:
            continue
    return held


def _mapped(pid: int) -> set[int]:
    """Inodes of the /dev/shm files a process maps."""
    inodes = set()
    for line in _read(Path(f'/proc/{pid}/maps')).decode(errors='replace').splitlines():
        parts = line.split(maxsplit=5)
        if len(parts) == 6 and parts[5].startswith(f'{SHM}/'):
            inodes.add(int(parts[4]))
    return inodes


def in_use() -> set[int]:
    """Inodes of /dev/shm files that a live process maps or holds open."""
    inodes = set()
    for pid in _pids():
        inodes |= _mapped(pid) | set(_held(pid).values())
    return inodes


def owned_shm(pid: int) -> set[str]:
    """The /dev/shm files a process owns: those it holds open (Fast DDS lock files), the
    segments and ports they lock with the ports' mutexes, and the other semaphores it maps."""
    held = set(_held(pid))
    owned = held | {name.removesuffix('_el') for name in held}
    owned |= {f'sem.{name}_mutex' for name in owned
              if name.startswith('fastrtps_port') and not name.endswith('_el')}
    mapped = _mapped(pid)
    return owned | {name for name, inode in shm_inodes().items()
                    if name.startswith('sem.') and not name.startswith('sem.fastrtps_')
                    and inode in mapped}


def stale_shm(before: Iterable[str]) -> set[str]:
    """Files of /dev/shm not in ``before`` that no live process maps or holds open (a Fast DDS
    port's mutex, which nobody keeps open, lives as long as its port)."""
    files, used, old = shm_inodes(), in_use(), set(before)

    def live(name: str) -> bool:
        port = re.fullmatch(r'sem\.(fastrtps_port\d+)_mutex', name)
        return files.get(port[1] if port else name) in used
    return {name for name in files if name not in old and not live(name)}


# --- commands -------------------------------------------------------------------------------
class Command:
    """A ``flexarm`` subprocess; its merged output lines with their arrival times."""

    def __init__(self, args: Iterable[str], env: dict[str, str]) -> None:
        self.started = time.monotonic()
        self.process = subprocess.Popen(
            [FLEXARM, *args], env={**env, 'PYTHONUNBUFFERED': '1'}, stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, errors='replace',
            start_new_session=True)
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

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
        try:
            self.process.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            pass


class Graph:
    """One ``flexarm up`` with its marker, the shared memory before it, and its faults."""

    def __init__(self, label: str, domain: int, robot: str, tag: str) -> None:
        self.label, self.domain, self.robot = label, domain, robot
        self.marker = f'{tag}-{label}'
        self.env = dict(os.environ)
        self.shm_before = set(shm_inodes())
        self.datasets: list[Path] = []
        self.rows: list[Row] = []
        self.owned: list[tuple[Row, set[str]]] = []   # files of each killed node
        self.at: tuple[float, float, float] | None = None   # target of the last goal
        self.up = self.start_up()

    def start_up(self, marker: str | None = None) -> Command:
        env = {**self.env, MARKER: marker or self.marker}
        return Command(['up', '--domain-id', str(self.domain), '--robot', self.robot,
                        '--rtf', str(RTF), '--timeout', str(READY_S),
                        '--name', f'faults-{marker or self.marker}'], env)

    def wait_ready(self) -> None:
        if self.up.wait_line(r'graph ready in', READY_S) is None:
            raise RuntimeError(f'{self.label} graph not ready: {self.up.last_line()}')

    def command(self, *args: str) -> Command:
        return Command([*args, '--domain-id', str(self.domain)], self.env)

    def run(self, *args: str, timeout: float = MOVE_S) -> Command:
        """Run a command to its end (killed after ``timeout``)."""
        command = self.command(*args)
        try:
            command.wait_exit(timeout)
        finally:
            command.kill()
        return command

    def kill_node(self, name: str, row: Row) -> float:
        """SIGKILL the node ``name``; the time of the kill."""
        pid = node_pid(self.marker, name)
        self.owned.append((row, owned_shm(pid)))
        os.kill(pid, signal.SIGKILL)
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
            client.kill()
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
            left = marked(self.marker) - descendants(root)
            return not left
        wait_until(none_left, SETTLE_S)
        return len(left)

    def stop(self, sig: int, row: Row) -> None:
        """Signal ``flexarm up``; detection, orphans and stale files of the whole graph."""
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
            row.add(f'left: {pid} {_read(Path(f"/proc/{pid}/cmdline"))[:80]!r}')
        self.attribute_stale(row)

    def attribute_stale(self, teardown: Row) -> None:
        """Stale files to the scenario that killed their owner, the rest to ``teardown``."""
        stale = stale_shm(self.shm_before)
        for row, files in self.owned:
            row.stale_shm += len(stale & files)
            stale -= files
        teardown.stale_shm += len(stale)
        if stale:
            teardown.add(f'stale: {sorted(stale)[:6]}')

    def close(self) -> None:
        """Stop everything left of this graph (after it was measured)."""
        if self.up.process.poll() is None:
            self.up.process.send_signal(signal.SIGTERM)
            self.up.wait_exit(TEARDOWN_S)
        self.up.kill()
        for pid in marked(self.marker):
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        for path in self.datasets:
            path.unlink(missing_ok=True)


# --- scenarios ------------------------------------------------------------------------------
def server_killed_mid_goal(graph: Graph, node: str, mode: str, row: Row) -> None:
    """Kill the goal's server or controller while the arm moves; a fresh goal recovers."""
    client = graph.long_goal(mode)
    try:
        killed = graph.kill_node(node, row)
        exited = client.wait_exit(DETECT_S)
    finally:
        client.kill()
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
        client.kill()
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
        client.kill()
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
        client.kill()
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
    """A second ``flexarm up`` in the domain: refused, nothing of it left, the first serves."""
    before = set(shm_inodes())
    marker = f'{graph.marker}-second'
    second = graph.start_up(marker)
    try:
        started_graph = second.wait_line(r'graph ready in', DETECT_S)   # None once it exits
        exited = second.wait_exit(SETTLE_S)
    finally:
        second.kill()
    if started_graph is None and exited is not None and second.process.returncode != 0:
        row.detected_s = exited - second.started
        row.add(second.last_line()[:120])
    else:
        row.add('NOT refused: ' + ' | '.join(line[:70] for _, line in second.lines[:2]))
    wait_until(lambda: not marked(marker), SETTLE_S)
    row.orphans = len(marked(marker))
    for pid in marked(marker):
        os.kill(pid, signal.SIGKILL)
    stale = stale_shm(before)
    row.stale_shm = len(stale)
    graph.shm_before |= stale            # counted here, not again at the teardown
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


def stop_graph(graph: Graph, sig: int, mid_goal: bool, row: Row) -> None:
    """Signal ``flexarm up`` (mid-goal or idle); every process of the graph must go."""
    client = graph.long_goal('rigid') if mid_goal else None
    try:
        graph.stop(sig, row)
    finally:
        if client is not None:
            client.kill()
            row.add(f'the goal: {client.last_line()}')


# --- the run --------------------------------------------------------------------------------
def attempt(graph: Graph, name: str, scenario: Callable[[Graph, Row], None]) -> Row:
    """Run one scenario; an error is reported in its row, not raised."""
    row = Row(name)
    graph.rows.append(row)
    try:
        scenario(graph, row)
    except (ScenarioError, OSError, RuntimeError, ValueError) as exc:
        row.add(f'error: {exc}')
    return row


Scenario = Callable[[Graph, Row], None]
# Per graph (label, robot): its scenarios in the order they run, each (key for --only, name,
# what it does).
GRAPHS: tuple[tuple[str, str, tuple[tuple[str, str, Scenario], ...]], ...] = (
    ('sim', 'sim', (
        ('compensator', 'compensator killed mid-goal',
         lambda g, r: server_killed_mid_goal(g, 'flexarm_compensator', 'rigid', r)),
        ('learner', 'learner killed mid-collection', learner_killed_mid_collection),
        ('vision_goal', 'vision killed mid-goal (closed loop)', vision_killed_mid_goal),
        ('vision_collection', 'vision killed mid-collection', vision_killed_mid_collection),
        ('second_up', 'second flexarm up in the domain', second_graph),
        ('sim', 'simulator killed mid-goal',
         lambda g, r: server_killed_mid_goal(g, 'flexarm_sim', 'rigid', r)),
        ('sigterm_idle', 'SIGTERM of flexarm up (idle)',
         lambda g, r: stop_graph(g, signal.SIGTERM, False, r)))),
    ('bridge', 'bridge', (
        ('second_client', 'second controller client (TCP)', second_controller_client),
        ('bridge', 'bridge killed mid-goal',
         lambda g, r: server_killed_mid_goal(g, 'flexarm_bridge', 'rigid', r)),
        ('sigterm_goal', 'SIGTERM of flexarm up mid-goal (bridge)',
         lambda g, r: stop_graph(g, signal.SIGTERM, True, r)))),
    ('kill', 'sim', (
        ('sigkill_goal', 'SIGKILL of flexarm up mid-goal',
         lambda g, r: stop_graph(g, signal.SIGKILL, True, r)),)),
)
KEYS = tuple(key for _, _, scenarios in GRAPHS for key, _, _ in scenarios)


def run_graph(label: str, robot: str, tag: str,
              scenarios: Iterable[tuple[str, str, Scenario]]) -> list[Row]:
    with reserved() as domain:
        graph = Graph(label, domain, robot, tag)
        try:
            graph.wait_ready()
            for _, name, scenario in scenarios:
                attempt(graph, name, scenario)
        except (RuntimeError, OSError) as exc:
            graph.rows.append(Row(f'{label} graph', note=f'error: {exc}'))
        finally:
            graph.close()
    print(f'# {robot} graph in ROS domain {domain}, logs in runs/faults-{graph.marker}/')
    for row in graph.rows:
        print_row(row)
    return graph.rows


def seconds(value: float | None) -> str:
    return '-' if value is None else f'{value:.2f}'


def print_row(row: Row) -> None:
    print(f'{row.scenario:<40} {seconds(row.detected_s):>10} {seconds(row.recovered_s):>11} '
          f'{row.lost_samples:>4} {row.orphans:>7} {row.stale_shm:>9}  {row.note}', flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--only', help=f'comma-separated scenarios of {", ".join(KEYS)} '
                        '(default: every one); a graph with none of them is not started')
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    args = parser.parse_args()
    only = set(args.only.split(',')) if args.only else set(KEYS)
    if only - set(KEYS):
        parser.error(f'unknown scenarios {sorted(only - set(KEYS))}; known: {", ".join(KEYS)}')
    started, tag = time.monotonic(), uuid.uuid4().hex[:8]
    print(f'{"scenario":<40} {"detected s":>10} {"recovered s":>11} {"lost":>4} '
          f'{"orphans":>7} {"stale shm":>9}  note', flush=True)
    rows: list[Row] = []
    for label, robot, scenarios in GRAPHS:
        chosen = [scenario for scenario in scenarios if scenario[0] in only]
        if chosen:
            rows += run_graph(label, robot, tag, chosen)
    detected = [r.detected_s for r in rows if r.detected_s is not None]
    summary = {'lost_samples': sum(r.lost_samples for r in rows),
               'orphans': sum(r.orphans for r in rows),
               'stale_shm': sum(r.stale_shm for r in rows),
               'max_detect_s': max(detected, default=None),
               'undetected': [r.scenario for r in rows if r.detected_s is None],
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
