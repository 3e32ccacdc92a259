"""Shared fixtures of the test suite, and what keeps its runs apart.

- Runtime files: ``FLEXARM_STATE_DIR`` is a temporary folder of the run (of each xdist
  worker), so no test reads or changes the operator's data, models, runs or calibration, and
  no test sees another run's.
- Liveness: ``FLEXARM_LIVENESS_SCALE`` is :data:`flexarm_core.liveness.UNDER_TEST` (unless
  set): the suite runs two workers on two cores, and a starved node is slow, not dead.
- ROS domains: a test module that starts nodes gets a domain no other module of the run uses
  (:class:`DomainPool`: taken for the whole run, and reserved the way domain_coordinator and
  ``flexarm up`` reserve one, so other runs on the machine skip it too); the domain is empty
  when the module starts (no process of this machine runs in it).
- DDS transports: nodes get the Fast DDS profile of their discovery range from the launcher
  (:mod:`flexarm_core.transport`); this process has none of its own, and the
  one a test's in-process ``flexarm`` command sets is removed when the test ends.
- Processes: every test stops the nodes it started and checks they were reaped; every process
  a module started (its scope token is inherited through the environment) is killed and reaped
  when the module ends, and the module fails if one was left behind.
"""
from __future__ import annotations

import contextlib
import os
import resource
import shutil
import signal
import socket
import tempfile
import time
import uuid
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

_STATE = Path(tempfile.mkdtemp(prefix='flexarm-test-state-'))
os.environ['FLEXARM_STATE_DIR'] = str(_STATE)   # before flexarm_core.paths is imported

from flexarm_core import liveness, processes  # noqa: E402

os.environ.setdefault(liveness.ENV, str(liveness.UNDER_TEST))
# The test processes and every command they start (CLI, benchmarks) use one BLAS thread, as the
# nodes do (flexarm_bringup's ros_env): a thread pool per process only costs its start.
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
SCOPE_ENV = 'FLEXARM_TEST_SCOPE'   # inherited by every process a test module starts
# multiprocessing's resource tracker serves this pytest process for its whole life (started
# by the first spawn of a test); it is not a test's process.
_RESOURCE_TRACKER = 'multiprocessing.resource_tracker'
REAP_WAIT = 5.0   # [s] for a killed process to vanish (SIGKILL: only the kernel's work)


LOG_TAIL = 40   # [lines] of each node log shown with a failed test


def pytest_sessionfinish(session: pytest.Session) -> None:
    shutil.rmtree(_STATE, ignore_errors=True)


_STARTED = pytest.StashKey[float]()
_CPU_AT_SETUP = pytest.StashKey[float]()
CPU_SHOWN = 15    # test modules in the run's CPU summary


def _cpu_seconds() -> float:
    """CPU time [s] of this process and of the processes it has reaped (user and system): a
    test's nodes, started by it or by a ``flexarm up`` it ran, are reaped when they end."""
    own, reaped = (resource.getrusage(who)
                   for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + reaped.ru_utime + reaped.ru_stime


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    item.stash[_STARTED] = time.time()
    item.stash[_CPU_AT_SETUP] = _cpu_seconds()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]
                              ) -> Iterator[pytest.TestReport]:
    """A failed test shows the tails of the node logs written during it: of the graphs
    ``flexarm up`` ran (the run's state folder is removed when the run ends), of those it
    started in its own folder and of its module's graph (``module_launch``). A node's own
    reason (or the stack a crash dumps) is what tells a slow graph from a broken one."""
    report = yield
    if call.when == 'teardown' and _CPU_AT_SETUP in item.stash:
        report.user_properties.append(('cpu_s', _cpu_seconds() - item.stash[_CPU_AT_SETUP]))
    if report.failed and call.when == 'call':
        started = item.stash.get(_STARTED, 0.0)
        funcargs = getattr(item, 'funcargs', {})
        folders = [_STATE / 'runs', funcargs.get('tmp_path'),
                   *(v.folder for v in funcargs.values() if isinstance(v, Launcher))]
        for path in sorted(p for f in folders if f is not None for p in Path(f).rglob('*.log')):
            if path.stat().st_mtime >= started:
                lines = path.read_text(errors='replace').splitlines()[-LOG_TAIL:]
                report.sections.append((f'node log {path.parent.name}/{path.name}',
                                        '\n'.join(lines)))
    return report


def pytest_terminal_summary(terminalreporter: Any) -> None:
    """Where the run's CPU went, by test module (the suite is CPU-bound on two cores: its time
    follows its CPU, and ``--durations`` shows wall time inflated by whatever ran alongside).
    A module's figure holds its fixtures' setup and teardown and the nodes it started."""
    by_module: Counter[str] = Counter()
    for reports in terminalreporter.stats.values():
        for report in reports:
            for name, value in getattr(report, 'user_properties', ()):
                if name == 'cpu_s':
                    by_module[report.nodeid.split('::', 1)[0]] += value
    if not by_module:
        return
    terminalreporter.write_sep('=', f'CPU by test module: {sum(by_module.values()):.0f} '
                                    f'core-s in all, the {CPU_SHOWN} largest')
    for module, seconds in by_module.most_common(CPU_SHOWN):
        terminalreporter.write_line(f'{seconds:7.1f} core-s  {module}')


DEFAULT_NODE_SECONDS = 10.0   # a node module without a ``duration`` mark


def _expected_seconds(item: pytest.Item) -> float:
    """How long the item's work unit is expected to run: its ``duration`` mark, else a guess
    from what it starts (nodes) or does not (pure unit tests: about nothing)."""
    mark = item.get_closest_marker('duration')
    if mark is not None:
        return float(mark.args[0])
    return DEFAULT_NODE_SECONDS if item.get_closest_marker('node') else 0.0


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The longest work units first (stable otherwise): with four workers on two cores, a
    long module that starts last is the run's tail while the other workers idle."""
    items.sort(key=lambda item: -_expected_seconds(item))


def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """xdist's ``loadscope`` (a module's tests on one worker: they may share its graph) in the
    collection's order (longest first) rather than by test count, with each test of a module
    that shares nothing between its tests (:data:`INDEPENDENT_MODULES`) a unit of its own."""
    if config.getvalue('dist') != 'loadscope':
        return None
    from xdist.scheduler import LoadScopeScheduling

    class LongestFirstScheduling(LoadScopeScheduling):
        def __init__(self, config: pytest.Config, log: Any = None) -> None:
            super().__init__(config, log)
            config.option.loadscopereorder = False

        def _split_scope(self, nodeid: str) -> str:
            if nodeid.split('::', 1)[0] in INDEPENDENT_MODULES:
                return nodeid
            return super()._split_scope(nodeid)

    return LongestFirstScheduling(config, log)


INDEPENDENT_MODULES = {'tests/test_benchmarks.py',   # each test runs its own script
                       'tests/endurance/test_endurance.py'}


def _processes_with(variable: str, value: str) -> dict[int, str]:
    """Live processes of this machine whose environment holds ``variable=value``: their
    command lines. Zombies are dead already and left out, and so is a process whose command
    line is gone by the time it is read: it was in the middle of its exit (its memory, the
    command line with it, is released before it becomes a zombie)."""
    found = {pid: ' '.join(processes.command_line(pid))
             for pid, env in processes.environments().items()
             if pid != os.getpid() and env.get(variable) == value}
    return {pid: command for pid, command in found.items() if command}


def _kill_and_reap(pids: list[int]) -> list[int]:
    """SIGKILL ``pids``; the ones still there after :data:`REAP_WAIT` s."""
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass
    deadline = time.monotonic() + REAP_WAIT
    remaining = list(pids)
    while remaining and time.monotonic() < deadline:
        for pid in list(remaining):
            try:
                if os.waitpid(pid, os.WNOHANG)[0] == pid:
                    remaining.remove(pid)
                    continue
            except ChildProcessError:    # not our child: gone once it ended
                pass
            if not processes.alive(pid):
                remaining.remove(pid)
        time.sleep(0.02)
    return remaining


class DomainPool:
    """ROS domain ids for the run: each handed out once, held until the run ends.

    A domain is taken by reserving it (:mod:`flexarm_bringup.domains`), which
    ``flexarm up`` and parallel runs respect, and only if no process of this machine is in it.
    """

    def __init__(self) -> None:
        self._held: dict[int, socket.socket | None] = {}    # None: lent (:meth:`lent`)

    def take(self) -> int:
        from flexarm_bringup import domains

        for did in range(domains.FIRST, domains.LAST + 1):
            if did in self._held:
                continue
            sock = domains.hold(did)
            if sock is None:
                continue
            if did in domains.in_use():          # used without a reservation
                sock.close()
                continue
            self._held[did] = sock
            return did
        raise RuntimeError('no free ROS domain left for this test run')

    @contextlib.contextmanager
    def lent(self, did: int) -> Iterator[None]:
        """The reservation of the run's domain ``did`` released for the block, for a process
        of the test to take (``flexarm up`` refuses an exported domain that another process
        reserves), and taken back after it. Start that process in ``did`` before the block (it
        takes the reservation once the block has begun): no other module of the run, and no
        free-domain search (``domains.first_free``), takes a domain a process runs in, and a
        domain nobody runs in and nobody reserves is free for anyone."""
        from flexarm_bringup import domains

        sock = self._held[did]
        assert sock is not None, f'domain {did} is lent already'
        self._held[did] = None
        sock.close()
        try:
            yield
        finally:
            self._held[did] = domains.hold(did)

    def close(self) -> None:
        for sock in self._held.values():
            if sock is not None:
                sock.close()
        self._held.clear()


@pytest.fixture(scope='session')
def domain_pool() -> Iterator[DomainPool]:
    pool = DomainPool()
    yield pool
    pool.close()


@pytest.fixture(scope='module', autouse=True)
def _no_process_left_behind(request: pytest.FixtureRequest) -> Iterator[None]:
    """Tag every process the module starts; kill and reap what is left when it ends."""
    token = f'{request.module.__name__}-{uuid.uuid4().hex[:8]}'
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(SCOPE_ENV, token)
        yield
    left = {pid: cmd for pid, cmd in _processes_with(SCOPE_ENV, token).items()
            if _RESOURCE_TRACKER not in cmd}
    stuck = _kill_and_reap(list(left))
    if left:
        pytest.fail(f'{len(left)} process(es) outlived their test and were killed'
                    f'{f" ({len(stuck)} could not be reaped)" if stuck else ""}: '
                    + '; '.join(f'{pid}: {cmd[:160]}' for pid, cmd in left.items()),
                    pytrace=False)


@pytest.fixture(autouse=True)
def _transport_env_restored() -> Iterator[None]:
    """Undo the Fast DDS profile that ``flexarm``'s ``main`` called in this process puts in its
    environment (:func:`flexarm_core.transport.apply`): a later test's processes
    of another discovery range (tests/test_hosts.py: SUBNET) must not inherit it."""
    from flexarm_core.transport import PROFILES_ENV, SKIP_CWD_ENV

    saved = {key: os.environ.get(key) for key in (PROFILES_ENV, SKIP_CWD_ENV)}
    yield
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


@pytest.fixture(scope='module')
def domain_id(domain_pool: DomainPool) -> Iterator[int]:
    """The module's own ROS domain (empty when taken); also in the environment of the tests
    (in-process rclpy contexts) and of every process they start."""
    did = domain_pool.take()
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv('ROS_DOMAIN_ID', str(did))
        patch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
        yield did


class Launcher:
    """``launcher(name, robot='sim', namespace='', **parameters)`` starts the node ``name`` of
    config/graph.yaml exactly as ``flexarm up`` does (``robot`` picks the controller entry,
    default ``sim``; ``namespace``: one arm of several); :meth:`stop_all` stops them (SIGINT,
    then SIGKILL) and checks each was reaped. A node that moves the arm (the learner, the
    compensator) comes with its arm's owner, as in every graph, unless ``arm_owner=False``."""

    MOVERS = frozenset({'learner', 'compensator'})

    def __init__(self, domain_id: int, folder: Path) -> None:
        self._domain_id, self.folder = domain_id, folder
        self.started: list[Any] = []

    def __call__(self, name: str, robot: str = 'sim', namespace: str = '',
                 arm_owner: bool = True, **parameters: Any) -> Any:
        from flexarm_bringup.launcher import (
            NodeProcess,
            load_graph,
            load_optional,
            load_rehearsal,
            ros_env,
        )

        specs = {**{s.name: s for s in load_rehearsal()}, **load_optional(robot),
                 **{s.name: s for s in load_graph(robot)}}
        owner = next(s for s in specs.values() if s.role == 'arm_owner')
        if arm_owner and specs[name].role in self.MOVERS and not any(
                n.spec.name == owner.name and n.namespace == namespace.strip('/')
                and n.returncode is None for n in self.started):
            self(owner.name, robot, namespace)
        log = self.folder / (f'{namespace}_{name}.log' if namespace else f'{name}.log')
        node = NodeProcess(specs[name], ros_env(self._domain_id, self.folder / 'ros_log'),
                           log, parameters, namespace)
        node.start()
        self.started.append(node)
        return node

    def stop_all(self) -> None:
        from flexarm_bringup.launcher import stop_all

        codes = stop_all(self.started, timeout=5.0)
        running = [name for name, code in codes.items() if code is None]
        assert not running, f'node(s) {running} could not be stopped and reaped'


@pytest.fixture
def launch(domain_id: int, tmp_path: Path) -> Iterator[Launcher]:
    """Nodes of one test (:class:`Launcher`), stopped when it ends."""
    launcher = Launcher(domain_id, tmp_path)
    yield launcher
    launcher.stop_all()


@pytest.fixture(scope='module')
def module_launch(domain_id: int, tmp_path_factory: pytest.TempPathFactory
                  ) -> Iterator[Launcher]:
    """Nodes shared by the tests of one module (:class:`Launcher`), stopped when it ends: for
    a graph the module's tests use without disturbing each other."""
    launcher = Launcher(domain_id, tmp_path_factory.mktemp('module_graph'))
    yield launcher
    launcher.stop_all()


@pytest.fixture
def ros_node(domain_id: int, request: pytest.FixtureRequest) -> Iterator[Any]:
    """An rclpy node in its own context on the test's domain, spun in a background thread by a
    ``SingleThreadedExecutor``, as every node's ``main()`` spins it. What a test creates on it
    stays until the test ends: destroying a subscription while the executor thread builds its
    wait set kills that thread ("cannot use Destroyable"), and the test then waits for
    messages nothing takes any more. Not a ``MultiThreadedExecutor``: Jazzy's shuts down its
    guard condition before its thread pool, and a callback still queued there then fails on
    it, an exception nothing retrieves, printed whenever the garbage collector frees it, in
    whichever later test runs then (test_sim_node left three a run).

    Parameters of the node: ``@pytest.mark.parametrize('ros_node', [{'use_sim_time': True}],
    indirect=True)``.
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from flexarm_core.ros.node_main import Spin

    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    node = rclpy.create_node('test_client', context=context, parameter_overrides=[
        Parameter(name, value=value) for name, value in getattr(request, 'param', {}).items()])
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    spin = Spin(executor, lambda: None)
    try:
        yield node
    finally:
        # The spin ends before anything of the node goes: a wait set still being built from
        # a destroyed entity raises in the spin thread ("cannot use Destroyable"), and so
        # does an executor shut down while it spins (its guard condition is gone).
        assert spin.stop(10.0), "the test node's executor did not stop"
        executor.shutdown(timeout_sec=2.0)
        assert spin.error is None, f'the test node\'s executor failed: {spin.error!r}'
        for waitable in list(node.waitables):   # a test's action servers: destroy_node
            waitable.destroy()                   # leaves them, and the node, alive
        node.destroy_node()
        rclpy.try_shutdown(context=context)


@pytest.fixture
def wait_for() -> Callable[..., Any]:
    """``wait_for(condition, timeout, what)``: bounded polling for tests."""
    return _wait_for


def _wait_for(condition: Callable[[], Any], timeout: float, what: str) -> Any:
    """Poll ``condition`` until it returns something truthy; fail the test after ``timeout``
    wall seconds times the liveness factor (a limit on "it never comes", not a timing)."""
    timeout = liveness.limit(timeout)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.02)
    pytest.fail(f'timed out after {timeout:.1f} s waiting for {what}')


@pytest.fixture
def write_dataset() -> Callable[..., None]:
    """``write_dataset(path, count=12, bad=None)``: a dataset file of a smooth deflection at
    ``count`` random joints; sample ``bad`` is 10 mm off."""
    return _write_dataset


def _write_dataset(path: Path, count: int = 12, bad: int | None = None) -> None:
    import numpy as np

    from flexarm_deflection.dataset import DatasetWriter, Sample

    joints = np.random.default_rng(0).uniform([-0.3, 0.5, -1.5, -1.0], [0.3, 0.8, 0.3, 1.0],
                                               (count, 4))
    with DatasetWriter(path) as writer:
        for i, q in enumerate(joints):
            deflection = np.array([1e-3 * q[0], -0.01 * q[1], 1e-3 * q[3]])
            if i == bad:
                deflection[:2] += [0.006, -0.008]
            writer.append(Sample(i, q, 0.0, np.zeros(3), deflection, deflection, 6, 1e-5))


@pytest.fixture
def ready_client(domain_id: int) -> Iterator[Callable[..., Any]]:
    """``ready_client(**what)``: a FlexarmClient in a context of its own on the test's domain,
    after ``wait_until_ready(timeout=30, **what)``; destroyed when the test ends."""
    import rclpy
    from rclpy.context import Context

    from flexarm_control.ros.client import FlexarmClient

    made: list[tuple[Any, Any]] = []

    def make(**what: Any) -> Any:
        context = Context()
        rclpy.init(context=context, domain_id=domain_id)
        client = FlexarmClient('test_client', context=context)
        made.append((client, context))
        client.wait_until_ready(timeout=liveness.limit(30.0), **what)
        return client

    yield make
    for client, context in made:
        client.destroy_node()
        rclpy.try_shutdown(context=context)
