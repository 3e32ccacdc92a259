"""Start flexarm nodes as OS processes: what ``flexarm up`` and the node-level tests share.

ROS ``launch`` is not available from PyPI, so a node is started as
``python -m <module> --ros-args -r __node:=<name> --params-file config/<file> ...`` in a
clean environment (own ROS_DOMAIN_ID, localhost discovery, log directory) and in its own
session, so that only the supervisor decides when it gets a signal.
"""
from __future__ import annotations

import contextlib
import functools
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import IO, Any

import yaml

from flexarm_core.dds_shm import SHM_DIR, listened_ports, owned_shm, remove_shm_of_dead
from flexarm_core.params import SAFE_LOADER, config_layers, load_config
from flexarm_core.parent_death import signal_on_parent_death
from flexarm_core.transport import transport_env

# Set by ros-wheels-bootstrapper after it re-executed Python with LD_LIBRARY_PATH; a child
# that inherits it skips its own re-exec, and imports rclpy only if it inherits that path too.
_BOOTSTRAP_GUARD = '_ROS_WHEELS_BOOTSTRAP_COMPLETE'
DISCOVERY_RANGES = ('LOCALHOST', 'SUBNET')
BLAS_THREADS_ENV = 'OPENBLAS_NUM_THREADS'   # numpy's BLAS (ros_env)


@dataclass(frozen=True)
class NodeSpec:
    """One node of the graph, as described in ``config/graph.yaml``."""

    name: str
    module: str
    role: str = ''
    params_files: tuple[str, ...] = ()
    parameters: Mapping[str, Any] = field(default_factory=dict)
    restart: bool = False
    remappings: Mapping[str, str] = field(default_factory=dict)   # a site's: topic -> topic

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> NodeSpec:
        return cls(name=d['name'], module=d['module'], role=d.get('role', d['name']),
                   params_files=tuple(d.get('params_files', ())),
                   parameters=dict(d.get('parameters') or {}),
                   restart=bool(d.get('restart', False)))


def _graph_file(path: Path | None) -> dict[str, Any]:
    """graph.yaml (``path``, else config/'s), with a site's layer (:func:`config_layers`): its
    ``robots`` and ``robot_settings`` entries replace those of the same robot, and its
    ``remappings`` (per node name: {topic: topic}) are added to the nodes'."""
    layers = [path] if path else config_layers('graph.yaml')
    graph: dict[str, Any] = {}
    for layer in layers:
        with open(layer, encoding='utf-8') as f:
            doc = yaml.load(f, Loader=SAFE_LOADER) or {}
        if not graph:
            graph = doc
            continue
        for key in ('robots', 'robot_settings'):
            graph[key] = {**graph.get(key, {}), **(doc.get(key) or {})}
        graph['remappings'] = {**graph.get('remappings', {}), **(doc.get('remappings') or {})}
    return graph


def load_graph(robot: str = 'sim', path: Path | None = None) -> list[NodeSpec]:
    """Node specs of the graph for a robot entry (``sim``, ``bridge``, ``ros2_control``) of
    graph.yaml, each with the entry's settings it lists in ``robot_parameters``."""
    graph = _graph_file(path)
    settings = robot_settings(robot, path)
    return [_with_settings(d, settings, graph)
            for d in [*(graph['robots'][robot] or ()), *graph['nodes']]]


def robot_settings(robot: str = 'sim', path: Path | None = None) -> dict[str, Any]:
    """The parameters a robot entry gives its nodes (graph.yaml ``robot_settings``): the
    graph's clock (``use_sim_time``) and how moves are sent (``motion.joint_commands``)."""
    graph = _graph_file(path)
    if robot not in graph['robots']:
        raise ValueError(f'unknown robot {robot!r}; graph.yaml defines {sorted(graph["robots"])}')
    return dict(graph['robot_settings'][robot])


def _with_settings(d: Mapping[str, Any], settings: Mapping[str, Any],
                   graph: Mapping[str, Any]) -> NodeSpec:
    spec = NodeSpec.from_dict(d)
    wanted = d.get('robot_parameters') or ()
    return replace(spec, parameters={**{k: settings[k] for k in wanted}, **spec.parameters},
                   remappings=dict((graph.get('remappings') or {}).get(spec.name) or {}))


def load_optional(robot: str = 'sim', path: Path | None = None) -> dict[str, NodeSpec]:
    """Nodes of graph.yaml started only on request (e.g. the recorder), by name, each with the
    settings of the robot entry it lists in ``robot_parameters``."""
    settings, graph = robot_settings(robot, path), _graph_file(path)
    return {d['name']: _with_settings(d, settings, graph) for d in graph.get('optional') or ()}


def load_rehearsal(path: Path | None = None) -> list[NodeSpec]:
    """The programs of graph.yaml that stand in for a site's controller and camera driver
    (``rehearsal``: started by ``flexarm rehearse``, never by ``flexarm up``)."""
    graph = _graph_file(path)
    return [_with_settings(d, {}, graph) for d in graph.get('rehearsal') or ()]


def all_nodes(path: Path | None = None) -> list[NodeSpec]:
    """Every node graph.yaml describes, robot entries first, each once."""
    graph = _graph_file(path)
    entries = [*(d for nodes in graph['robots'].values() for d in nodes or ()),
               *graph['nodes'], *(graph.get('optional') or ()), *(graph.get('rehearsal') or ())]
    return list({d['name']: NodeSpec.from_dict(d) for d in entries}.values())


def node_name(role: str, path: Path | None = None) -> str:
    """Name graph.yaml gives the node of ``role`` (``learner``: ``flexarm_learner``), so that
    the tools address the nodes a renamed graph runs."""
    names = {spec.role: spec.name for spec in all_nodes(path)}
    if role not in names:
        raise ValueError(f'graph.yaml has no node of role {role!r}; roles: {sorted(names)}')
    return names[role]


def node_parameters(spec: NodeSpec) -> dict[str, Any]:
    """The parameters the node of ``spec`` starts with (nested), as it is started: its params
    files under its name, then the robot entry's settings; no per-run overrides."""
    parameters = load_config(*spec.params_files, node_name=spec.name)
    for name, value in spec.parameters.items():
        *parents, leaf = name.split('.')
        node = parameters
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    return parameters


def controllers(path: Path | None = None) -> dict[str, str]:
    """Node name: robot entry, for the first node of each entry of graph.yaml (the arm's
    controller: where it runs, that robot entry is up)."""
    return {nodes[0]['name']: robot for robot, nodes in _graph_file(path)['robots'].items()
            if nodes}


def select_nodes(names: Sequence[str], only: Iterable[str]) -> list[str]:
    """The node names of ``names`` (in their order) that ``only`` asks for, each given by its
    full name or without the ``flexarm_`` prefix (``sim``: ``flexarm_sim``); ValueError
    naming what ``names`` does not hold, or if ``only`` names nothing."""
    short = {name.removeprefix('flexarm_'): name for name in names}
    wanted = [short.get(n, n) for n in (n.strip() for n in only) if n]
    unknown = [n for n in wanted if n not in names]
    if unknown or not wanted:
        raise ValueError(f'unknown node(s) {", ".join(unknown) or "(none given)"}; the graph '
                         f'has {", ".join(short)}')
    return [name for name in names if name in wanted]


def ros_env(domain_id: int, log_dir: Path | None = None,
            base: Mapping[str, str] | None = None,
            discovery: str = 'LOCALHOST') -> dict[str, str]:
    """Environment of a node process: isolated domain, discovery range and the transports
    that go with it, own log dir; a fatal signal (SIGSEGV at shutdown, say) dumps the Python
    stack of every thread into the node's log, so such a crash names where it happened.

    ``discovery`` (ROS_AUTOMATIC_DISCOVERY_RANGE) is LOCALHOST unless the caller widens it on
    purpose: the DDS of the PyPI wheels has no security plugins, so every participant that
    reaches the graph can publish commands to it. With LOCALHOST every transport stays on
    this machine too (:mod:`flexarm_core.transport`).

    numpy's BLAS runs one thread (``OPENBLAS_NUM_THREADS``, unless set): a node's matrices are
    a few joints or holes wide, too small to share out, and the pool OpenBLAS starts at import
    costs a node 0.2 core-seconds of its start (0.52 -> 0.32 for the simulator's imports). The
    training job limits its threads itself (:mod:`flexarm_deflection.training_job`).

    The bootstrapper's guard is kept only where ``env`` already holds its library path
    (:func:`_bootstrapped`): a child without that path re-executes itself to get it.
    """
    if discovery not in DISCOVERY_RANGES:
        raise ValueError(f'discovery range {discovery!r}; choose one of {DISCOVERY_RANGES}')
    env = dict(os.environ if base is None else base)
    if not _bootstrapped(env):
        env.pop(_BOOTSTRAP_GUARD, None)
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = discovery
    env['PYTHONUNBUFFERED'] = '1'
    env['PYTHONFAULTHANDLER'] = '1'
    env.setdefault(BLAS_THREADS_ENV, '1')
    if log_dir is not None:
        env['ROS_LOG_DIR'] = str(log_dir)
    return transport_env(env)


@functools.cache
def _ros_library_dirs() -> frozenset[str]:
    """The directories ros-wheels-bootstrapper puts on LD_LIBRARY_PATH for this interpreter
    (its own rule: ``<prefix>/lib`` and site-packages' ``ros_*.libs``)."""
    site = Path(sys.prefix, 'lib', f'python{sys.version_info.major}.{sys.version_info.minor}',
                'site-packages')
    return frozenset({str(Path(sys.prefix, 'lib')),
                      *(str(libs.resolve()) for libs in site.glob('ros_*.libs') if libs.is_dir())})


def _bootstrapped(env: Mapping[str, str]) -> bool:
    """Whether a child of this interpreter started with ``env`` already has what the
    bootstrapper's re-exec would give it (its guard and every ROS library directory): then
    the child keeps the guard and starts once instead of twice, ~25 ms of CPU and of wall
    time less for each node (measured on 2 cores: ``import rclpy, numpy`` 0.215 -> 0.19 s)."""
    have = set(env.get('LD_LIBRARY_PATH', '').split(os.pathsep))
    return bool(env.get(_BOOTSTRAP_GUARD)) and _ros_library_dirs() <= have


def node_command(spec: NodeSpec, overrides_file: Path | None = None, namespace: str = ''
                 ) -> list[str]:
    """Command line of a node: its module, name (and ``namespace``: one arm's graph under
    ``/<namespace>``), its params files, then ``overrides_file``.

    Per-run parameters go in a params file of their own, last, under the node's name: a
    ``-p name:=value`` would lose against a node-specific entry of config/ (rcl applies
    ``-p`` like a ``/**`` entry, and node-specific entries win).
    """
    cmd = [sys.executable, '-m', spec.module, '--ros-args', '-r', f'__node:={spec.name}']
    if namespace.strip('/'):
        cmd += ['-r', f'__ns:=/{namespace.strip("/")}']
    for name in spec.params_files:
        for path in config_layers(name):
            cmd += ['--params-file', str(path)]
    for source, target in spec.remappings.items():
        cmd += ['-r', f'{source}:={target}']
    if overrides_file is not None:
        cmd += ['--params-file', str(overrides_file)]
    return cmd


def write_overrides(spec: NodeSpec, extra: Mapping[str, Any] | None, path: Path) -> Path | None:
    """Write graph.yaml's and the caller's parameters of ``spec`` as a params file."""
    parameters = {**spec.parameters, **(extra or {})}
    if not parameters:
        return None
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump({f'/**/{spec.name}': {'ros__parameters': parameters}}),
                    encoding='utf-8')
    return path


class NodeProcess:
    """A running node: its process, its log file, and a clean way to stop it."""

    def __init__(self, spec: NodeSpec, env: Mapping[str, str], log_path: Path,
                 extra: Mapping[str, Any] | None = None, namespace: str = '') -> None:
        self.spec = spec
        self.namespace = namespace.strip('/')
        self.log_path = log_path
        self._env = dict(env)
        self.parameters = dict(extra or {})   # the caller's, over graph.yaml's
        self._log: IO[bytes] | None = None
        self.process: subprocess.Popen[bytes] | None = None
        self.restarts = 0
        self.reported = False     # its death was reported and it stays down
        self.killed_shm: list[Path] = []   # what its ended processes left, until nobody uses it
        self.shm: ShmWatch | None = None    # what its running process owns of it

    def start(self) -> None:
        self._ended()                            # the previous process, before a restart
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        self._log = open(self.log_path, 'ab')
        overrides = write_overrides(self.spec, self.parameters,
                                    self.log_path.with_suffix('.params.yaml'))
        self.process = subprocess.Popen(
            node_command(self.spec, overrides, self.namespace), env=self._env,
            stdin=subprocess.DEVNULL, stdout=self._log, stderr=subprocess.STDOUT,
            start_new_session=True, preexec_fn=_terminate_with_parent)
        self.shm = ShmWatch(self.process)

    @property
    def returncode(self) -> int | None:
        return None if self.process is None else self.process.poll()

    def signal(self, sig: int) -> None:
        """Send ``sig`` to the node's process group. Before a SIGKILL, which leaves its Fast
        DDS shared memory behind, note what it owns as it is then (:class:`ShmWatch`)."""
        if self.process is not None and self.process.poll() is None:
            if sig == signal.SIGKILL and self.shm is not None:
                self.shm.look()
            os.killpg(self.process.pid, sig)

    def log_tail(self, lines: int = 10) -> str:
        try:
            text = self.log_path.read_text(encoding='utf-8', errors='replace')
        except OSError:
            return ''
        return '\n'.join(text.splitlines()[-lines:])

    def close(self) -> None:
        if self.returncode is not None:
            self._ended()
        if self._log is not None:
            self._log.close()
            self._log = None

    def _ended(self) -> None:
        """Its process is gone (or was never started): what it left joins :attr:`killed_shm`,
        and of that what nobody uses is removed. A signal (a SIGKILL, also someone else's, or a
        crash) left all it owned; a clean exit, at most the ports it listened on: Fast DDS
        removes a port with its last user, and a dead peer that had it open still counts."""
        if self.shm is not None:
            owned = self.shm.stop()
            killed = self.returncode is not None and self.returncode < 0
            self.killed_shm += owned if killed else listened_ports(owned)
            self.shm = None
        remove_shm_of_dead(self.killed_shm)


def _terminate_with_parent() -> None:
    """In the child before exec: get SIGTERM when the thread that started it dies.

    The backstop for a supervisor killed with SIGKILL, which can stop nothing itself. Linux
    sends the signal when the starting *thread* ends, so nodes are started from threads that
    live as long as the graph (the main thread, or a watchdog that ends with the graph).
    """
    signal_on_parent_death(signal.SIGTERM)


@contextlib.contextmanager
def _signals_ignored(*signals: int) -> Iterator[None]:
    """Ignore ``signals`` meanwhile (main thread only): a second Ctrl-C can't cut a shutdown."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, signal.SIG_IGN) for sig in signals}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def stop_all(nodes: Iterable[NodeProcess], timeout: float = 5.0) -> dict[str, int | None]:
    """SIGINT every node, wait up to ``timeout``, then SIGTERM, then SIGKILL what remains.

    Returns each node's exit code. SIGINT and SIGTERM to the caller are ignored meanwhile
    (the shutdown is bounded). A node killed with SIGKILL leaves Fast DDS shared-memory
    files behind; the ones it owned are removed (:func:`owned_shm`).
    """
    with _signals_ignored(signal.SIGINT, signal.SIGTERM):
        return _stop_all(list(nodes), timeout)


def _stop_all(nodes: list[NodeProcess], timeout: float) -> dict[str, int | None]:
    for sig, wait in ((signal.SIGINT, timeout), (signal.SIGTERM, 2.0), (signal.SIGKILL, 2.0)):
        alive = [n for n in nodes if n.process is not None and n.returncode is None]
        if not alive:
            break
        for node in alive:
            node.signal(sig)
        deadline = time.monotonic() + wait
        while time.monotonic() < deadline and any(n.returncode is None for n in alive):
            time.sleep(0.02)
    codes = {}
    for node in nodes:
        if node.process is not None:
            try:
                node.process.wait(timeout=1.0)
            except subprocess.TimeoutExpired:
                pass
        node.close()
        codes[node.spec.name] = node.returncode
    return codes


SHM_LOOK_S = 1.0      # [s] between two looks at what a node process owns of the shared memory
SHM_SETTLE_S = 5.0    # [s] the looks go on after /dev/shm changed: discovery maps the new ports


class ShmWatch:
    """What a running process owns of the shared memory (:func:`owned_shm`), noted while it
    lives: a process that a signal ends (a crash, a SIGKILL from anyone) leaves it behind, and
    gone, it can no longer be asked. A thread looks every :data:`SHM_LOOK_S` while ``shm_dir``
    changed within :data:`SHM_SETTLE_S` (a participant came or went: the process made its
    segments, or maps a newcomer's ports). A look takes some 2 ms; a quiet machine costs a stat
    a second, one where a participant comes every 2 s 0.02 cores for a graph of 7 nodes (2-core
    AMD EPYC, 2026-11-29)."""

    def __init__(self, process: subprocess.Popen[bytes], shm_dir: Path = SHM_DIR) -> None:
        self._process, self._dir = process, shm_dir
        self.owned: set[Path] = set()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True,
                                        name=f'shm-watch-{process.pid}')
        self._thread.start()

    def look(self) -> None:
        """Note what the process owns now (nothing once it has ended: a pid is not asked once
        it is free for another process)."""
        if self._process.poll() is None:
            found = owned_shm(self._process.pid, self._dir)
            with self._lock:
                self.owned.update(found)

    def stop(self) -> list[Path]:
        """End the looks; what was noted."""
        self._stop.set()
        self._thread.join()
        return sorted(self.owned)

    def _run(self) -> None:
        changed, seen = time.monotonic(), None
        while self._process.poll() is None and not self._stop.wait(SHM_LOOK_S):
            with contextlib.suppress(OSError):
                mtime = self._dir.stat().st_mtime_ns
                if mtime != seen:
                    changed, seen = time.monotonic(), mtime
                if time.monotonic() - changed <= SHM_SETTLE_S:
                    self.look()
