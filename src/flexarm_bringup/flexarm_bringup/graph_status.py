"""What ``flexarm status`` reports: a running graph seen from outside, with or without one.

:func:`query` asks the graph of the client's ROS domain (node discovery, the latched model
topics of the learner and the compensator, ``/joint_states``' rate, every node's
``/diagnostics``, the payload and bag parameters); :func:`supervisor_record` finds the
``flexarm up`` that runs the domain (its run folder's ``graph.json``: node processes, restarts
and exit codes); :func:`graph_problems` says what is wrong: a node of the record whose process
is gone, and every ERROR a node reports (a damaged calibration file or model record names the
file and the reason there: the node that reads a file is the one that knows, on any host);
:func:`status_text` formats the result for humans (mm and deg). Everything in the returned
dict is SI and JSON-able. A graph split over hosts (``flexarm up --only``) is seen as far as
the client's discovery range reaches: the nodes of every host with
ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET (or ROS_STATIC_PEERS), and the supervisor record is this
machine's, which names its own part and the remote one (a node that died on another host is
seen only as missing).

:mod:`flexarm_bringup.status_text` makes the lines;
:mod:`flexarm_bringup.graph_watch` is the same view for ``flexarm up``.
"""
from __future__ import annotations

import functools
import json
import math
import os
import time
from collections.abc import Callable, Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.srv import GetParameters
from rclpy.parameter import parameter_value_to_python
from rclpy.qos import QoSDurabilityPolicy, QoSProfile
from sensor_msgs.msg import JointState

from flexarm_bringup.launcher import all_nodes, controllers, load_graph, node_name
from flexarm_bringup.status_text import (
    Heard,
    calibration_text,
    clock_text,
    real_time_factor,
)
from flexarm_core import liveness, processes, topics
from flexarm_core.graph_locks import RECORD
from flexarm_core.health_report import ERROR, LEVEL_NAMES
from flexarm_deflection.models import model_metadata
from flexarm_msgs.msg import ModelHealth, ModelInfo

NOT_DIAGNOSED = frozenset({'foxglove'})   # roles of the nodes that publish no /diagnostics
DIAGNOSTICS_WAIT = 3.0   # [s, wall; liveness-scaled] for every running node's first report
LATCHED = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)


@functools.cache
def graph_node_names() -> list[str]:
    """Every node name config/graph.yaml knows, controller entries first."""
    return [spec.name for spec in all_nodes()]


@functools.cache
def diagnosed(names: frozenset[str]) -> frozenset[str]:
    """Those of ``names`` that report on ``/diagnostics``."""
    return names - {node_name(role) for role in NOT_DIAGNOSED}


def arm_status_name(name: str, namespace: str) -> str | None:
    """A ``/diagnostics`` status name without the arm's namespace if a flexarm node of the arm
    in ``namespace`` reports it (``arm1/flexarm_vision: camera_info`` -> ``flexarm_vision:
    camera_info`` for ``arm1``), else None: another arm's, or not a flexarm node's."""
    ns = namespace.strip('/')
    own = name.removeprefix(f'{ns}/') if ns else name
    if ns and own == name:
        return None
    return own if own.split(': ', 1)[0] in graph_node_names() else None


def heard(msg: DiagnosticArray, namespace: str) -> dict[str, Heard]:
    """The statuses of one ``/diagnostics`` message that the arm in ``namespace`` reports."""
    found = {}
    for s in msg.status:
        name = arm_status_name(s.name, namespace)
        if name is not None:
            level = s.level[0] if isinstance(s.level, bytes) else int(s.level)
            found[name] = Heard(level, s.message, {v.key: v.value for v in s.values})
    return found


def reporting_nodes(statuses: Mapping[str, Heard]) -> set[str]:
    """The nodes that ``statuses`` come from."""
    return {name.split(': ', 1)[0] for name in statuses}


def graph_problems(errors: Mapping[str, str], record: Mapping[str, Any] | None,
                   alive: Callable[[int], bool] = processes.alive,
                   silent_controller: str | None = None) -> list[str]:
    """What is wrong with the graph, a line each: the nodes of the supervisor ``record`` whose
    process is gone (the supervisor restarts only some, and a dead one is otherwise merely
    absent from discovery), a controller that runs but publishes no joint states
    (``silent_controller``: its kind; a stopped simulator clock, a lost link), then the ERROR
    statuses ``errors`` (name: message; a node's own word on what is broken)."""
    problems = []
    if silent_controller:
        problems.append(f'controller {silent_controller}: no joint states for '
                        f'{JOINT_STATES_WAIT:g} s (a stopped /clock, a lost link, a stuck '
                        'driver); goals fail with CONTROLLER_TIMEOUT')
    for name, node in (record or {}).get('nodes', {}).items():
        code, pid = node.get('exit_code'), node.get('pid')
        if code is not None:
            problems.append(f'{name} is down: it exited with code {code} and was not '
                            f'restarted (its log: {Path(record["run_dir"]) / name}.log)')
        elif pid is None or not alive(pid):
            problems.append(f'{name} is down: its process {pid} is gone')
    return problems + [f'{name}: {message}' for name, message in sorted(errors.items())]


class ErrorLog:
    """What ``flexarm up`` has said of the ERROR statuses: each once when it appears or
    changes, and once when it is over."""

    def __init__(self) -> None:
        self._said: dict[str, str] = {}

    def update(self, statuses: Mapping[str, Heard]) -> list[str]:
        """Lines for the ERRORs of ``statuses`` not said yet, and the ones that are over."""
        lines = []
        for name, h in sorted(statuses.items()):
            if h.level == ERROR and self._said.get(name) != h.message:
                self._said[name] = h.message
                lines.append(f'PROBLEM {name}: {h.message}')
            elif h.level != ERROR and self._said.pop(name, None) is not None:
                lines.append(f'resolved {name}: {LEVEL_NAMES[h.level]} {h.message}')
        return lines


def supervisor_record(runs_dir: Path, domain_id: int, namespace: str = ''
                      ) -> dict[str, Any] | None:
    """The graph record of the live supervisor of ``domain_id`` (and the arm in
    ``namespace``) under ``runs_dir``, if any."""
    for path in sorted(Path(runs_dir).glob(f'*/{RECORD}'), key=lambda p: p.stat().st_mtime,
                       reverse=True):
        try:
            record = json.loads(path.read_text())
            pid = int(record['supervisor_pid'])
            if (record['domain_id'] != domain_id
                    or record.get('namespace', '') != namespace.strip('/')):
                continue
            os.kill(pid, 0)
        except (OSError, ValueError, KeyError, TypeError):
            continue          # unreadable, or its supervisor is gone
        return record | {'run_dir': str(path.parent)}
    return None


def record_nodes(record: Mapping[str, Any] | None,
                 alive: Callable[[int], bool] = processes.alive) -> tuple[set[str], set[str]]:
    """What a supervisor ``record`` says runs: its nodes on this machine whose process lives,
    and the remote ones (other hosts', only discovery can tell)."""
    if record is None:
        return set(), set()
    here = {name for name, node in record.get('nodes', {}).items()
            if node.get('exit_code') is None and node.get('pid') and alive(node['pid'])}
    return here, set(record.get('remote', ()))


def model_summary(info: ModelInfo | None) -> dict[str, Any] | None:
    """A model announcement as a dict; ``age_s`` from the model file's creation time."""
    if info is None:
        return None
    summary = {'version': info.version, 'kind': info.kind, 'dataset': info.dataset,
               'payloads': list(info.payloads), 'samples': info.metrics.samples,
               'validation': info.metrics.validation,
               'max_error': [info.metrics.max_error_x, info.metrics.max_error_y,
                             info.metrics.max_error_phi],
               'warning': info.warning, 'path': info.path, 'age_s': None, 'refresh': None}
    try:
        meta = model_metadata(info.path)
        summary['age_s'], summary['refresh'] = _age(meta), _refresh(meta)
    except (OSError, ValueError):
        pass              # another machine's path, or a damaged file: no age
    return summary


def file_summary(version: str, path: Path, meta: dict[str, Any]) -> dict[str, Any]:
    """A model file's metadata in the form of :func:`model_summary`."""
    metrics = meta.get('metrics') or {}
    origin = meta.get('provenance') or {}
    return {'version': version, 'kind': meta['kind'], 'dataset': origin.get('dataset', ''),
            'payloads': origin.get('payloads', []),
            'samples': metrics.get('samples', meta.get('samples', 0)),
            'validation': metrics.get('validation', ''),
            'max_error': [metrics.get(f'max_error_{a}', math.nan) for a in ('x', 'y', 'phi')],
            'warning': '', 'path': str(path), 'age_s': _age(meta), 'refresh': _refresh(meta)}


def _refresh(meta: dict[str, Any]) -> dict[str, Any] | None:
    """What a refreshed model was made from: the version it corrected, the refresh's dataset,
    samples and median residuals [m] before and after (None: trained, not refreshed)."""
    corrections = meta.get('corrections') or []
    if 'refresh_of' not in meta or not corrections:
        return None
    last = corrections[-1]
    return {'of': meta['refresh_of'], 'dataset': meta.get('refresh_dataset', ''),
            'samples': last.get('samples', 0), 'residual_before': last.get('residual_before'),
            'residual_after': last.get('residual_after')}


def _age(meta: dict[str, Any]) -> float | None:
    """Seconds since a model was trained (its ``created`` stamp), None if unknown."""
    try:
        created = datetime.fromisoformat(meta['created'])
    except (KeyError, TypeError, ValueError):
        return None
    return (datetime.now(UTC) - created).total_seconds()


def query(client: Any, namespace: str = '', record: Mapping[str, Any] | None = None
          ) -> dict[str, Any]:
    """The status of the graph in ``client``'s domain (``client``: a FlexarmClient of the arm
    in ``namespace``; ``record``: its supervisor's, if it runs on this machine). The record's
    nodes whose process lives are up, whether or not this fresh participant has discovered
    them yet (that can take a node's next periodic DDS announcement, seconds); without a
    record, up means discovered.

    Everything is listened for at once and each wait ends on its event: discovery once the
    graph is seen, the diagnostics once every running node has reported, the latched models
    once those the nodes report are in, the parameters once answered; each bounded
    (liveness-scaled) for a node that does not answer."""
    ns = namespace.strip('/')
    got: dict[str, Any] = {}
    joint_states: list[float] = []       # when each message was sent [s, publisher's clock]
    stamps: list[float] = []             # and its stamp [s, the graph's clock]
    statuses: dict[str, Heard] = {}
    subscriptions = [
        client.create_subscription(ModelInfo, topics.MODEL,
                                   lambda m: got.__setitem__('learner', m), LATCHED),
        client.create_subscription(ModelHealth, topics.MODEL_HEALTH,
                                   lambda m: got.__setitem__('health', m), LATCHED),
        client.create_subscription(JointState, topics.JOINT_STATES,
                                   lambda m, info: (
                                       joint_states.append(info['source_timestamp'] * 1e-9),
                                       stamps.append(m.header.stamp.sec
                                                     + 1e-9 * m.header.stamp.nanosec)), 100),
        client.create_subscription(DiagnosticArray, topics.DIAGNOSTICS,
                                   lambda m: statuses.update(heard(m, ns)), 10)]
    here, remote = record_nodes(record)
    found = _discover(client, ns, remote if record is not None else None)
    running = here | {name for space, name in found if space == ns}
    nodes = {name: name in running for name in graph_node_names()}
    controller = next((kind for name, kind in controllers().items() if nodes.get(name)), None)
    wanted = {key: (node_name(role), name) for key, (role, name) in PARAMETERS.items()
              if nodes[node_name(role)]}
    with ParameterReads(client, wanted) as parameters:
        reporting = diagnosed(frozenset(running & set(graph_node_names())))
        since = time.monotonic()
        reports_end = since + liveness.limit(DIAGNOSTICS_WAIT)

        def complete() -> bool:
            reported = (time.monotonic() >= reports_end
                        or (not reporting - reporting_nodes(statuses)
                            and latched_in(statuses, got, client.active_model)))
            return (reported and parameters.done()
                    and (controller is None or _rate_known(joint_states, since)))

        while not complete():
            parameters.send()
            client.spin_once(0.02)
        values = parameters.values
    status = {
        'domain_id': client.context.get_domain_id(),
        'nodes': nodes,
        'controller': controller,
        'arms': sorted({space for space, name in found if name in controllers()}),
        'joint_state_rate_hz': joint_state_rate(stamps),
        'real_time_factor': real_time_factor(statuses.get(sim_controller_status_name())),
        'clock': clock_text(statuses.get(sim_controller_status_name())),
        'learner_model': model_summary(got.get('learner')),
        'active_model': model_summary(client.active_model),
        'model_health': health_summary(got.get('health')),
        'errors': {name: h.message for name, h in sorted(statuses.items())
                   if h.level == ERROR},
        'payload_kg': {'learner': values.get('learner_payload'),
                       'simulated': values.get('simulated_payload')},
        'camera_calibration': calibration_text(statuses.get(calibration_status_name())),
        'bag': values.get('bag'),
    }
    for subscription in subscriptions:
        client.destroy_subscription(subscription)
    return status


# What status reads of the nodes' parameters: key: (node's role, parameter)
PARAMETERS = {'learner_payload': ('learner', 'payload'),
              'simulated_payload': ('simulator', 'plant.payload'),
              'bag': ('recorder', 'bag_name')}
PARAMETER_WAIT = 4.0      # [s, wall; liveness-scaled] for a node's parameter service to answer
# [s] an unanswered parameter request is sent again after this: a server may not have
# discovered this fresh client's reply channel yet and answers into the void; a get is
# harmless twice, and the first answer counts
PARAMETER_RESEND = 0.25
JOINT_STATES_SPAN = 0.25  # [s] of joint states that give their rate (6 bursts at 25 Hz)
JOINT_STATES_WAIT = 1.0   # [s, wall; liveness-scaled] without one: NO joint states


def sim_controller_status_name() -> str:
    """Name of the simulator's ``controller`` status on ``/diagnostics``."""
    return f'{node_name("simulator")}: controller'


class ParameterReads:
    """Parameters of several nodes asked at once, one GetParameters client per node (of the
    client's arm) reused for the resends; a context manager that destroys its clients."""

    def __init__(self, client: Any, wanted: Mapping[str, tuple[str, str]]) -> None:
        self._node, self._wanted = client, dict(wanted)
        self._names: dict[str, list[str]] = {}          # node: the parameters asked of it
        for node, name in self._wanted.values():
            self._names.setdefault(node, []).append(name)
        self._services = {node: client.create_client(GetParameters, f'{node}/get_parameters')
                          for node in self._names}
        self._sent: dict[str, tuple[float, list[Any]]] = {}   # node: (last sent, futures)
        self._deadline = time.monotonic() + liveness.limit(PARAMETER_WAIT)

    def send(self) -> None:
        """Send the first request to each node whose service is there, or send again."""
        now = time.monotonic()
        for node, service in self._services.items():
            last, futures = self._sent.get(node, (-math.inf, []))
            if (now - last >= PARAMETER_RESEND and self._answer(node) is None
                    and now < self._deadline and service.service_is_ready()):
                futures.append(service.call_async(GetParameters.Request(names=self._names[node])))
                self._sent[node] = (now, futures)

    def done(self) -> bool:
        """Whether every node has answered, or the wait for them is over."""
        return (time.monotonic() >= self._deadline
                or all(self._answer(node) is not None for node in self._services))

    def _answer(self, node: str) -> list[Any] | None:
        """The values a node answered, None while it has not."""
        futures = self._sent.get(node, (0.0, []))[1]
        return next((f.result().values for f in futures if f.done() and f.result()), None)

    @property
    def values(self) -> dict[str, Any]:
        """Each wanted parameter's value, None if its node did not answer."""
        values = {}
        for key, (node, name) in self._wanted.items():
            answer = self._answer(node)
            values[key] = (None if not answer
                           else parameter_value_to_python(
                               answer[self._names[node].index(name)]))
        return values

    def __enter__(self) -> ParameterReads:
        return self

    def __exit__(self, *exc: object) -> None:
        for service in self._services.values():
            self._node.destroy_client(service)


def joint_state_rate(sent: list[float]) -> float:
    """[Hz] of messages stamped ``sent`` [s]: on the graph's clock, the controller's own rate
    (sim time: the simulator's ``joint_state_rate``, whatever its real-time factor), from the
    median interval between consecutive stamps: the simulator's messages leave in bursts, one
    per /clock, faster than status takes them, and the oldest of a burst may be dropped; 0 for
    fewer than two distinct stamps."""
    steps = np.diff(np.asarray(sent, dtype=float))
    steps = steps[steps > 0]
    return 0.0 if steps.size == 0 else float(1.0 / np.median(steps))


def _rate_known(sent: list[float], since: float) -> bool:
    """Whether joint states came over :data:`JOINT_STATES_SPAN`, or none came for
    :data:`JOINT_STATES_WAIT` after ``since`` (the graph was discovered)."""
    if sent:
        return sent[-1] - sent[0] >= JOINT_STATES_SPAN
    return time.monotonic() - since >= liveness.limit(JOINT_STATES_WAIT)


def latched_in(statuses: Mapping[str, Heard], got: Mapping[str, Any], active: Any) -> bool:
    """Whether the latched model messages the nodes' reports announce have come: the
    learner's model, the compensator's active one and its health (each published once a
    model exists, which the node's ``model`` status names)."""
    def has_model(node: str) -> bool:
        report = statuses.get(f'{node}: model')
        return report is not None and bool(report.values.get('version'))

    return ((not has_model(node_name('learner')) or 'learner' in got)
            and (not has_model(node_name('compensator'))
                 or (active is not None and 'health' in got)))


def calibration_status_name() -> str:
    """Name of the vision node's ``tool calibration`` status on ``/diagnostics``."""
    return f'{node_name("vision")}: tool calibration'


def health_summary(msg: ModelHealth | None) -> dict[str, Any] | None:
    """The compensator's model health as plain data (None if it was not heard)."""
    if msg is None:
        return None
    return {'model_version': msg.model_version, 'stale': msg.stale, 'summary': msg.summary,
            'stale_residual': msg.stale_residual, 'bound_factor': msg.bound_factor,
            'angle_bound_factor': msg.angle_bound_factor, 'bound_goals': msg.bound_goals,
            'bound_misses': msg.bound_misses,
            'regions': [{'name': r.name, 'observations': r.observations,
                         'median_position_residual': r.median_position_residual,
                         'max_position_residual': r.max_position_residual,
                         'stale': r.stale} for r in msg.regions]}


def _discover(client: Any, namespace: str, expected: set[str] | None, settle: float = 1.0,
              empty: float = 3.0, longest: float = 6.0) -> set[tuple[str, str]]:
    """(namespace, name) of the domain's nodes once discovery has settled.

    A fresh participant learns of the others one by one, seconds apart under load: wait until
    the ``expected`` nodes of the arm in ``namespace`` are seen (none: at once); not knowing
    what to expect (None), until every node of a controller's graph.yaml entry is seen in some
    namespace, then ``settle`` more seconds for optional ones, or until nothing of flexarm is
    seen for ``empty`` seconds; at most ``longest`` (a graph with a node down). Each limit
    liveness-scaled."""
    ours = set(graph_node_names())
    graphs = {name: {s.name for s in load_graph(robot)} for name, robot in controllers().items()}
    settle, empty, longest = map(liveness.limit, (settle, empty, longest))
    start = time.monotonic()
    complete_since = None
    while True:
        client.spin_once(0.02)
        now = time.monotonic()
        found = {(space.strip('/'), name)
                 for name, space in client.get_node_names_and_namespaces()}
        spaces: dict[str, set[str]] = {}
        for space, name in found:
            spaces.setdefault(space, set()).add(name)
        if expected is not None and expected <= spaces.get(namespace, set()):
            return found
        complete = expected is None and any(name in names and graph <= names
                                        for names in spaces.values()
                                        for name, graph in graphs.items())
        complete_since = (complete_since or now) if complete else None
        if (now - start > longest or (complete and now - complete_since > settle)
                or (not any(names & ours for names in spaces.values())
                    and now - start > empty)):
            return found


