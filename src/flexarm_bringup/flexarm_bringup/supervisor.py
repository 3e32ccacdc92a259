"""The running graph: start every node of config/graph.yaml, wait until it is ready, supervise.

Used by ``flexarm up``, ``flexarm demo``/``benchmark`` and the node-level tests. One log file
per node in the run folder. A graph refuses to start in a ROS domain that another graph of this
machine holds (a lock file per domain, :data:`LOCK_DIR`: immediate and certain, where discovery
can take seconds under load), or where a node of one of its names already runs (another
flexarm graph, perhaps on another host: two simulators would publish ``/clock`` and
``/joint_states``, and the learner could measure against the other arm's joints), and it is
ready only when each of its own nodes is discovered, besides the topics and servers. The
supervisor's probe node that checks the domain in :meth:`Graph.start` also serves
:meth:`Graph.wait_ready`: Fast DDS discovered most nodes that joined after the probe's initial
announcements only at its first periodic one, ~3.5 s after the probe appeared, so a probe made
before the nodes start has the graph ready ~1 s sooner (4.0 s, not 4.9 s: benchmarks/bringup.py).
A node that dies is reported with its exit code and the last lines of its log, and restarted if
graph.yaml says so (at most ``max_restarts`` times); the rest keeps running. :meth:`Graph.stop`
shuts everything down (SIGINT, SIGTERM, SIGKILL) and removes stale Fast DDS shared-memory
files. The run folder's ``graph.json`` (:data:`RECORD`) says which supervisor runs which
node processes in which domain, how often each was restarted and the exit code of one that
stays down (``flexarm status`` names a node whose process is gone).

Several arms: a graph with a ``namespace`` runs every node under ``/<namespace>`` (its names are
relative: :mod:`flexarm_core.topics`), with the learner's data and model folders and the
tool calibration in a subfolder ``<namespace>`` of the configured ones, so arms of one domain
share nothing but ``/clock`` and ``/diagnostics``. The domain lock and the name check are per
namespace. The first arm's simulator publishes ``/clock``; a graph that finds a ``/clock``
publisher when it starts has its simulator follow it (``clock_source``, flexarm_sim; a
follower takes the clock over when its publisher goes). :meth:`Graph.start` reports which.

Several hosts: a graph with ``only`` starts just those nodes (``flexarm up --only sim,vision``)
and leaves the rest of graph.yaml's (:attr:`Graph.remote`; optional nodes are never expected)
to other hosts of the domain; DDS carries everything between them. It is ready when its own
nodes, the remote ones (by name) and the whole graph's topics and servers are discovered; the
name check at start and the supervision concern only its own nodes, and :meth:`Graph.stop`
stops only those. The domain lock stays per machine: a graph is split over hosts, not over
shells of one machine.
"""
from __future__ import annotations

import contextlib
import fcntl
import json
import os
import time
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

from flexarm_bringup.launcher import (
    NodeProcess,
    NodeSpec,
    all_nodes,
    load_graph,
    load_optional,
    node_name,
    robot_settings,
    ros_env,
    select_nodes,
    stop_all,
)
from flexarm_core import liveness, topics
from flexarm_core.atomic_file import atomic_write
from flexarm_core.goal_sender import full_name
from flexarm_core.graph_locks import LOCK_DIR, RECORD, lock_name, lock_text
from flexarm_core.params import load_config
from flexarm_core.paths import SITE

# Wall-clock limits, times the liveness factor (flexarm_core.liveness):
DISCOVERY_WAIT = 1.0   # [s] to discover the nodes already running in a domain
CLOCK_WAIT = 5.0       # [s] more for a namespaced arm to find another arm's /clock
# Per-arm folders: (node's role, parameter).
ARM_FOLDERS = (('learner', 'data_directory'), ('learner', 'model_directory'),
               ('vision', 'tool_calibration_file'), ('vision', 'camera_calibration_file'))
# What "ready" means: what must be discovered in the graph (and /clock on sim time).
READY_TOPICS = (topics.JOINT_STATES, topics.TIP_POSE)
READY_ACTIONS = (topics.MOVE_TO_POSE, topics.COLLECT_SAMPLES)
READY_SERVICES = (topics.TRAIN,)
ACTION_STATUS = '{}/_action/status'   # an action server's goal status topic


class Graph:
    """The node processes of one run, in one ROS domain."""

    def __init__(self, domain_id: int, run_dir: Path, robot: str = 'sim',
                 parameters: Mapping[str, Mapping[str, Any]] | None = None,
                 optional: tuple[str, ...] = (), max_restarts: int = 3,
                 report: Callable[[str], None] = print, discovery: str = 'LOCALHOST',
                 namespace: str = '', only: tuple[str, ...] = ()) -> None:
        specs, self.remote = graph_specs(robot, optional, only)
        self._published, self._subscribed = ready_topics(robot_settings(robot))
        self.domain_id, self.run_dir, self.robot = domain_id, run_dir, robot
        self.namespace = namespace.strip('/')
        self._lock: int | None = None      # file descriptor of the domain lock while started
        self.max_restarts, self._report = max_restarts, report
        env = ros_env(domain_id, run_dir / 'ros_log', discovery=discovery)
        parameters = arm_folders(parameters or {}, self.namespace)
        self.nodes = {spec.name: NodeProcess(spec, env, run_dir / f'{spec.name}.log',
                                             parameters.get(spec.name), self.namespace)
                      for spec in specs if spec.name not in self.remote}
        self._discovery = contextlib.ExitStack()   # holds the probe of start() until ready
        self._started_probe: Any = None

    def start(self) -> None:
        """Start every node; RuntimeError, and nothing started, if another graph of this
        machine holds the domain or the domain already runs a node of one of their names."""
        self._lock = lock_domain(self.domain_id, self.namespace)
        try:
            self._started_probe = self._discovery.enter_context(self._probe())
            self._check_domain_free(self._started_probe)
            self._choose_clock(self._started_probe)
        except BaseException:
            self._close_probe()
            self._release()
            raise
        self.run_dir.mkdir(parents=True, exist_ok=True)
        for node in self.nodes.values():
            node.start()
        self._write_record()

    def _check_domain_free(self, probe: Any) -> None:
        deadline = time.monotonic() + liveness.limit(DISCOVERY_WAIT)
        while time.monotonic() < deadline:
            taken = sorted(name for name, ns in probe.get_node_names_and_namespaces()
                           if name in self.nodes and ns.strip('/') == self.namespace)
            if taken:
                raise RuntimeError(
                    f'ROS domain {self.domain_id} already runs {", ".join(taken)}: another '
                    'flexarm graph? Stop it, or start this one with another domain id')
            time.sleep(0.1)

    def _choose_clock(self, probe: Any) -> None:
        """The simulator follows a ``/clock`` another arm's simulator already publishes: looked
        for during the name check and, for an arm in a namespace (one of several), up to
        ``CLOCK_WAIT`` more (Fast DDS may announce a publisher only seconds after its node).
        Reported either way: who publishes the domain's clock."""
        sim = self.nodes.get(node_name('simulator'))
        if sim is None:
            return
        chosen = sim.parameters.get('clock_source')
        deadline = time.monotonic() + (liveness.limit(CLOCK_WAIT) if self.namespace else 0.0)
        while chosen is None and not probe.count_publishers(topics.CLOCK):
            if time.monotonic() >= deadline:
                chosen = 'own'
            else:
                time.sleep(0.1)
        if chosen is None:
            chosen = sim.parameters['clock_source'] = 'follow'
        owners = sorted(full_name(p.node_namespace, p.node_name)
                        for p in probe.get_publishers_info_by_topic(topics.CLOCK))
        self._report(f'clock: {sim.spec.name} publishes the /clock of ROS domain {self.domain_id}'
                     if chosen == 'own' else
                     f'clock: {sim.spec.name} follows the /clock of ROS domain {self.domain_id}'
                     + (f' ({", ".join(owners)})' if owners else ''))

    def _close_probe(self) -> None:
        self._started_probe = None
        self._discovery.close()

    def _release(self) -> None:
        if self._lock is not None:
            os.close(self._lock)          # closing the descriptor releases the lock
            self._lock = None

    def _write_record(self) -> None:
        record = {'supervisor_pid': os.getpid(), 'domain_id': self.domain_id,
                  'robot': self.robot, 'namespace': self.namespace, 'remote': self.remote,
                  'nodes': {name: {'pid': node.process.pid if node.process else None,
                                   'restarts': node.restarts, 'exit_code': node.returncode}
                            for name, node in self.nodes.items()}}
        atomic_write(self.run_dir / RECORD, lambda f: f.write(json.dumps(record).encode()))

    @contextlib.contextmanager
    def _probe(self) -> Iterator[Any]:
        """A node of the supervisor's own in the graph's domain, for discovery."""
        import rclpy
        from rclpy.context import Context

        context = Context()
        rclpy.init(context=context, domain_id=self.domain_id)
        node = rclpy.create_node('flexarm_supervisor', context=context,
                                 namespace=f'/{self.namespace}' if self.namespace else '')
        try:
            yield node
        finally:
            node.destroy_node()
            rclpy.try_shutdown(context=context)

    def wait_ready(self, timeout: float) -> None:
        """Wait until this graph's nodes, topics, actions and services are discovered.

        Raises TimeoutError naming what did not come up (and any node that died meanwhile).
        """
        started = time.monotonic()
        try:
            node = self._started_probe or self._discovery.enter_context(self._probe())
            while True:
                missing = self._missing(node)
                if not missing:
                    return
                dead = self.check()
                waited = time.monotonic() - started
                if dead and not self._restarted(dead):
                    raise TimeoutError(f'graph not ready: {", ".join(dead)} died after '
                                       f'{waited:.0f} s; missing {", ".join(missing)}')
                if waited > timeout:
                    raise TimeoutError(f'graph not ready after {timeout:.0f} s: missing '
                                       f'{", ".join(missing)}{self._remote_hint()}')
                time.sleep(0.2)
        finally:
            self._close_probe()

    def _missing(self, node: Any) -> list[str]:
        ns = self.namespace
        found_nodes = {name for name, space in node.get_node_names_and_namespaces()
                       if space.strip('/') == ns}
        found_topics = {name for name, _ in node.get_topic_names_and_types()}
        found_services = {name for name, _ in node.get_service_names_and_types()}
        missing = [f'node {name}' for name in self.nodes if name not in found_nodes]
        missing += [f'remote node {name}' for name in self.remote if name not in found_nodes]
        missing += [t for t in (topics.absolute(t, ns) for t in self._published)
                    if t not in found_topics or not node.count_publishers(t)]
        missing += [f'a subscriber of {t}' for t in (topics.absolute(t, ns)
                                                     for t in self._subscribed)
                    if not node.count_subscribers(t)]
        missing += [a for a in (topics.absolute(a, ns) for a in READY_ACTIONS)
                    if f'{a}/_action/send_goal' not in found_services]
        missing += [s for s in (topics.absolute(s, ns) for s in READY_SERVICES)
                    if s not in found_services]
        return missing

    def _remote_hint(self) -> str:
        """What a partial graph needs from the other hosts, for a timeout's message."""
        if not self.remote:
            return ''
        return (f' (this host runs only part of the graph: {", ".join(self.remote)} must run '
                f'on other hosts in ROS_DOMAIN_ID={self.domain_id}, every host with '
                '--discovery subnet or ROS_STATIC_PEERS naming the others)')

    def _restarted(self, names: list[str]) -> bool:
        """Whether :meth:`check` restarted all these dead nodes (it marks the others)."""
        return not any(self.nodes[n].reported for n in names)

    def check(self) -> list[str]:
        """Report nodes that died since the last check, restart those allowed; their names."""
        dead = []
        for name, node in self.nodes.items():
            code = node.returncode
            if code is None or node.reported:
                continue
            dead.append(name)
            tail = node.log_tail(8).replace('\n', '\n    ')
            self._report(f'node {name} exited with code {code}; last log lines:\n    {tail}')
            if node.spec.restart and node.restarts < self.max_restarts:
                node.restarts += 1
                node.close()
                node.start()
                self._report(f'node {name} restarted ({node.restarts}/{self.max_restarts})')
            else:
                node.reported = True
                why = (f'restarted {node.restarts} times already' if node.spec.restart
                       else 'graph.yaml does not restart it')
                self._report(f'node {name} stays down ({why}): the graph runs without it')
        if dead:
            self._write_record()
        return dead

    def stop(self, timeout: float = 5.0) -> dict[str, int | None]:
        self._close_probe()
        try:
            return stop_all(self.nodes.values(), timeout)
        finally:
            self._release()

    def __enter__(self) -> Graph:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def graph_specs(robot: str, optional: tuple[str, ...] = (), only: tuple[str, ...] = ()
                ) -> tuple[list[NodeSpec], tuple[str, ...]]:
    """The nodes of a graph of ``robot`` with the ``optional`` ones, and those of them left to
    other hosts (``only``: this host's part; the rest, never an optional node, is remote);
    ValueError naming an unknown robot or node."""
    specs = load_graph(robot)
    extra = load_optional(robot)
    here = select_nodes([*(s.name for s in specs), *extra], only) if only else []
    optional = tuple(dict.fromkeys([*optional, *(n for n in here if n in extra)]))
    unknown = set(optional) - set(extra)
    if unknown:
        raise ValueError(f'unknown optional nodes {sorted(unknown)}; known: {sorted(extra)}')
    specs += [extra[name] for name in optional]
    remote = tuple(s.name for s in specs if here and s.name not in here
                   and s.name not in optional)
    return specs, remote


def ready_topics(settings: Mapping[str, Any]) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The topics a ready graph publishes and those it listens to, for a robot entry's
    ``settings``: ``/clock`` only on sim time (a real arm's graph runs on wall time), and the
    command topic of its ``motion.joint_commands`` (a controller executes what is sent); for
    ``follow_joint_trajectory`` the status its controller's action server publishes."""
    clock = (topics.CLOCK,) if settings.get('use_sim_time') else ()
    kind = settings.get('motion.joint_commands')
    if kind == 'follow_joint_trajectory':
        return (*READY_TOPICS, *clock, ACTION_STATUS.format(topics.FOLLOW_JOINT_TRAJECTORY)), ()
    commands = topics.JOINT_TRAJECTORY if kind == 'trajectory' else topics.JOINT_COMMANDS
    return (*READY_TOPICS, *clock), (commands,)


def arm_folders(parameters: Mapping[str, Mapping[str, Any]], namespace: str
                ) -> dict[str, dict[str, Any]]:
    """``parameters`` with the per-arm folders of ``namespace`` (none for ''): the learner's
    data and model folders and the vision node's tool calibration file, as configured (or as
    given) with a ``<namespace>`` subfolder."""
    result = {name: dict(values) for name, values in parameters.items()}
    if not namespace:
        return result
    specs = {spec.role: spec for spec in all_nodes()}
    for role, name in ARM_FOLDERS:
        node = specs[role].name
        configured = load_config(*specs[role].params_files, node_name=node)[name]
        value = Path(str(result.get(node, {}).get(name, configured)))
        result.setdefault(node, {})[name] = str(
            value.parent / namespace / value.name if value.suffix else value / namespace)
    return result


def lock_domain(domain_id: int, namespace: str = '') -> int:
    """An exclusive lock on ``domain_id`` (and ``namespace``) for this process (a file
    descriptor, held until closed, released by the kernel if the process dies); RuntimeError
    naming the holder. The file says who holds it: the supervisor's pid and the site folder
    it runs in (:func:`flexarm_core.graph_locks.lock_text`)."""
    LOCK_DIR.mkdir(parents=True, exist_ok=True)
    fd = os.open(LOCK_DIR / lock_name(domain_id, namespace), os.O_RDWR | os.O_CREAT, 0o666)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.read(fd, 64).decode(errors='replace').split('\n')[0].strip() or 'unknown'
        os.close(fd)
        raise RuntimeError(f'ROS domain {domain_id} is in use by another flexarm graph on this '
                           f'machine (supervisor pid {holder}): stop it, or start this one with '
                           'another domain id') from None
    os.ftruncate(fd, 0)
    os.pwrite(fd, lock_text(os.getpid(), SITE).encode(), 0)
    return fd
