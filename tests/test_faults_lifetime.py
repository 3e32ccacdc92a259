"""What outlives what, and what the operator is told: a harness killed mid-run leaves no
process behind; `flexarm up` and `flexarm status` name a damaged file or a dead node (status
exits 5); `up` stopping removes no shared memory but its own nodes'; the harness counts the
shared memory its own processes left, and no other.

`flexarm up`, `flexarm status` and tests/endurance/faults.py run as processes, as an operator or a
CI job runs them, each dying with this test process (PR_SET_PDEATHSIG). Waits are on their
output lines and on processes' ends, bounded by liveness limits.
"""
from __future__ import annotations

import json
import os
import re
import secrets
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from flexarm_core import liveness, processes
from flexarm_core.dds_shm import SHM_DIR, owned_shm, remove_shm_of_dead
from flexarm_core.params import load_config
from flexarm_core.parent_death import terminate_with_parent
from flexarm_core.paths import CALIBRATION_DIR, MODELS_DIR, RUNS_DIR, repo_path
from flexarm_recording.results.outcome_text import Exit

pytestmark = [pytest.mark.node, pytest.mark.duration(90)]
REPO = Path(__file__).resolve().parents[1]
HARNESS_ENV = 'FLEXARM_TEST_HARNESS'    # inherited by every process of one harness run
READY_S = 60.0     # [s, liveness-scaled] for a graph to be ready
GONE_S = 30.0      # [s, liveness-scaled] for a stopped graph's processes to end
# a harness is killed mid-collection: once its collection stored a sample, its `flexarm up`
# was ready long before and its `flexarm collect` runs (each further sample: ~1 s more)
SAMPLES = 1


class Process:
    """A process of this test (dies with it), its stdout and stderr lines as they come."""

    def __init__(self, *args: str, env: dict[str, str] | None = None) -> None:
        self.process = subprocess.Popen(
            [sys.executable, *args], cwd=REPO,
            env={**os.environ, 'PYTHONUNBUFFERED': '1', **(env or {})},
            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            text=True, start_new_session=True, preexec_fn=terminate_with_parent)
        self.lines: list[str] = []
        self._cond = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.process.stdout:
            with self._cond:
                self.lines.append(line.rstrip('\n'))
                self._cond.notify_all()
        with self._cond:
            self._cond.notify_all()

    def wait_line(self, pattern: str, timeout: float) -> str:
        """The first line matching ``pattern``; the test fails if none comes in ``timeout``
        (liveness-scaled) seconds or the process ends first."""
        regex, deadline = re.compile(pattern), time.monotonic() + liveness.limit(timeout)
        with self._cond:
            while True:
                found = next((line for line in self.lines if regex.search(line)), None)
                if found is not None:
                    return found
                if not self._reader.is_alive():            # it ended and said all it said
                    pytest.fail(f'no line matching {pattern!r} before it ended: '
                                + '\n'.join(self.lines[-30:]))
                if time.monotonic() > deadline:
                    pytest.fail(f'no line matching {pattern!r}: ' + '\n'.join(self.lines[-30:]))
                self._cond.wait(0.2)

    def stop(self, sig: int = signal.SIGTERM) -> int:
        """Signal it and wait for its end (SIGKILL after ``GONE_S``) and for its last lines
        (read by a thread of their own, which a loaded machine may hold back); its exit code."""
        if self.process.poll() is None:
            self.process.send_signal(sig)
        try:
            code = self.process.wait(liveness.limit(GONE_S))
        except subprocess.TimeoutExpired:
            self.process.kill()
            pytest.fail(f'{self.process.args[1:3]} did not end within {GONE_S} s of {sig!r}')
        self._reader.join(liveness.limit(GONE_S))
        return code


def flexarm(*args: str) -> Process:
    return Process('-m', 'flexarm_cli', *args)


@pytest.fixture
def up(domain_id: int) -> Iterator[Callable[[], Process]]:
    """``up()``: ``flexarm up`` in the module's domain, once ready; stopped when the test ends."""
    started: list[Process] = []

    def start() -> Process:
        graph = flexarm('up', '--domain-id', str(domain_id), '--rtf', '5',
                        '--name', f'lifetime-{secrets.token_hex(3)}')
        started.append(graph)
        graph.wait_line(r'graph ready in', READY_S)
        return graph

    yield start
    for graph in started:
        graph.stop()


def status(domain_id: int) -> tuple[int, dict]:
    """``flexarm status --json`` in the module's domain: its exit code and JSON."""
    done = subprocess.run(
        [sys.executable, '-m', 'flexarm_cli', 'status', '--json', '--domain-id',
         str(domain_id)], cwd=REPO, capture_output=True, text=True,
        timeout=liveness.limit(60.0), preexec_fn=terminate_with_parent)
    return done.returncode, json.loads(done.stdout.strip().splitlines()[-1])


def processes_of(token: str) -> dict[int, str]:
    """Live processes whose environment carries the harness ``token``: their command lines."""
    found = {}
    for pid, env in processes.environments().items():
        if pid != os.getpid() and env.get(HARNESS_ENV) == token:
            found[pid] = ' '.join(processes.command_line(pid))
    return found


def record_pid(name: str, node: str) -> int:
    """The pid of ``node`` in the supervisor record of the run ``name``."""
    return json.loads((RUNS_DIR / name / 'graph.json').read_text())['nodes'][node]['pid']


@pytest.mark.timeout(300)
@pytest.mark.parametrize('sig', [signal.SIGTERM, signal.SIGKILL], ids=['SIGTERM', 'SIGKILL'])
def test_a_harness_killed_mid_run_leaves_no_process_behind(sig, wait_for):
    token = secrets.token_hex(4)
    data = repo_path(load_config('learner.yaml', node_name='flexarm_learner')['data_directory'])
    before = set(data.glob('faults-*-learner.jsonl'))
    harness = Process('tests/endurance/faults.py', '--only', 'learner', env={HARNESS_ENV: token})
    try:
        wait_for(lambda: any(len(path.read_bytes().splitlines()) > SAMPLES for path in
                             set(data.glob('faults-*-learner.jsonl')) - before),
                 READY_S + 30.0, f"the harness's collection to store {SAMPLES} sample(s)")
        commands = processes_of(token).values()
        assert any(' up ' in c for c in commands) and any(' collect ' in c for c in commands)
    finally:
        harness.stop(sig)
    wait_for(lambda: not processes_of(token), GONE_S,
             f'every process of the harness to end after its {signal.Signals(sig).name}')
    if sig == signal.SIGTERM:
        assert harness.process.returncode == 128 + signal.SIGTERM   # stopped, not killed


def damage(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


@pytest.fixture
def damaged_files() -> Iterator[tuple[Path, Path]]:
    """The tool calibration and the model record damaged, a model file v1 beside it (removed
    again when the test ends)."""
    calibration, record = CALIBRATION_DIR / 'tool_camera.json', MODELS_DIR / 'current.json'
    model = MODELS_DIR / 'A-gp-v1.model'
    damage(calibration, '{"tool_correction": [0.0001, ')
    damage(record, 'not json')
    model.write_bytes(b'')
    yield calibration, record
    for path in (calibration, record, model):
        path.unlink(missing_ok=True)


def test_damaged_files_are_named_by_up_and_make_status_fail(up, domain_id, damaged_files):
    calibration, record = damaged_files
    graph = up()
    graph.wait_line(rf'PROBLEM flexarm_vision: tool calibration: .*{re.escape(str(calibration))}'
                    ' is damaged', 10.0)
    graph.wait_line(rf'PROBLEM flexarm_learner: model: .*{re.escape(str(record))} is damaged '
                    r'\(.*\); versions on disk: v1 ', 10.0)
    assert any('model driving the arm: none: the learner could not announce one' in line
               for line in graph.lines)
    code, found = status(domain_id)
    assert code == Exit.DEGRADED == found['exit_code'], found
    problems = '\n'.join(found['problems'])
    assert f'{calibration} is damaged (' in problems and 'measured without it' in problems
    assert f'{record} is damaged (' in problems and 'versions on disk: v1' in problems
    assert 'no trained predictor' not in problems


def test_a_dead_simulator_makes_status_fail(up, domain_id):
    graph = up()
    name = graph.wait_line(r'logs in ', 1.0).rsplit('/', 1)[-1]
    pid = record_pid(name, 'flexarm_sim')
    left = owned_shm(pid)                    # its shared memory, removed at the end
    try:
        os.kill(pid, signal.SIGKILL)
        graph.wait_line(r'node flexarm_sim stays down', 10.0)
        code, found = status(domain_id)
    finally:
        graph.stop()
        remove_shm_of_dead(left)
    assert code == Exit.DEGRADED == found['exit_code'], found
    assert any(p.startswith('flexarm_sim is down: it exited with code -9')
               for p in found['problems']), found['problems']


@pytest.fixture
def foreign_shm() -> Iterator[list[Path]]:
    """Fast DDS-like files of no process of this test: a segment with its lock file, a port
    with its mutex (removed again when the test ends)."""
    segment = f'fastrtps_{secrets.token_hex(8)}'
    port = f'fastrtps_port{60000 + os.getpid() % 5000}'
    files = [SHM_DIR / name for name in (segment, f'{segment}_el', port, f'sem.{port}_mutex')]
    for path in files:
        path.write_bytes(b'\0' * 64)
    yield files
    for path in files:
        path.unlink(missing_ok=True)


def test_up_stopping_removes_no_shared_memory_but_its_nodes(up, foreign_shm):
    graph = up()
    name = graph.wait_line(r'logs in ', 1.0).rsplit('/', 1)[-1]
    pid = record_pid(name, 'flexarm_vision')
    own = [path for path in owned_shm(pid) if 'fastrtps_port' not in path.name]
    os.kill(pid, signal.SIGSTOP)       # deaf to SIGINT and SIGTERM: `up` must SIGKILL it
    graph.stop()
    assert any('flexarm_vision (-9)' in line for line in graph.lines), graph.lines[-3:]
    assert [path for path in foreign_shm if not path.exists()] == []
    assert own and [path for path in own if path.exists()] == []   # its segments: removed


def test_the_harness_counts_the_shared_memory_its_processes_left_and_no_other():
    sys.path.insert(0, str(REPO / 'tests' / 'endurance'))
    import faults

    token = secrets.token_hex(4)
    ours = SHM_DIR / f'fastrtps_probe{token}_el'     # a lock file, as Fast DDS keeps one
    foreign = SHM_DIR / f'fastrtps_foreign{token}_el'
    ledger = faults.ShmLedger(token)
    holder = Process('-c', f'import fcntl, os, signal; fd = os.open({str(ours)!r}, os.O_CREAT '
                     '| os.O_RDWR); fcntl.flock(fd, fcntl.LOCK_EX); print("held", flush=True); '
                     'signal.pause()', env={faults.MARKER: f'{token}-client'})
    try:
        holder.wait_line('held', 10.0)
        foreign.write_bytes(b'')          # made meanwhile by a process of no graph
        ledger.sample()
        assert ledger.left() == {}        # still in use
        holder.process.kill()             # leaves its file behind
        holder.process.wait(liveness.limit(5.0))
        assert ledger.left() == {ours.name: f'{token}-client'}
    finally:
        holder.stop(signal.SIGKILL)
        ours.unlink(missing_ok=True)
        foreign.unlink(missing_ok=True)
