"""Scriptable client of the flexarm graph, in the spirit of nav2_simple_commander.

    client = FlexarmClient()
    client.wait_until_ready()
    result = client.move_to(1.45, -0.15, math.radians(-45), mode='predictive')
    client.destroy_node()

Every call blocks with a timeout (seconds, wall clock) and raises :class:`TimeoutError` when
it runs out, or, for a goal, returns at once as a :class:`GoalRun` to poll and cancel from the
script's own loop (``move_async``, ``collect_async``; the blocking ones wait on it):

    run = client.move_async(1.45, -0.15, math.radians(-45), mode='rigid')
    while not run.done():          # spins the client up to 0.1 s
        print(run.feedback())
    result = run.result()      # or run.cancel()

A goal's errors: a goal that the server rejects raises :class:`GoalRejected` with its reason, and
one that ends without success but without an error code raises :class:`GoalFailed`. While a
goal runs the client watches its server (:class:`ServerWatch`): a server that stops answering
for ``SERVER_SILENCE`` seconds (times the liveness factor,
:mod:`flexarm_core.liveness`: killed) or is replaced by another instance (restarted: it
does not know the goal) raises :class:`ServerLost`, naming the node, instead of waiting out
the timeout. A timeout
or a Ctrl-C (KeyboardInterrupt) while a goal runs cancels it (bounded wait) before the
exception goes on, so the arm stops; Ctrl-C raises :class:`GoalInterrupted` (a
KeyboardInterrupt) with the cancelled goal's result, e.g. where the arm stopped.
:meth:`FlexarmClient.cancel_all` cancels whatever goal runs on the arm, whoever sent it
(``flexarm cancel``).
:func:`init_client` leaves SIGINT to Python: rclpy's own handler would shut the context down
before the cancel could be sent.

One module: :class:`FlexarmClient` is the whole scriptable API, and the goal handle and the
server watch exist only for it.

Units are SI (m, rad); converting from mm/deg is the caller's (the CLI's) business.
"""
from __future__ import annotations

import contextlib
import json
import os
import threading
import time
import uuid
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import rclpy
from action_msgs.msg import GoalStatus
from rclpy.action import ActionClient
from rclpy.action.client import ClientGoalHandle
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSDurabilityPolicy, QoSProfile
from rclpy.task import Future
from unique_identifier_msgs.msg import UUID

from flexarm_control.execution.modes import Mode
from flexarm_core import liveness, topics, transport
from flexarm_core.dds_shm import listened_ports, owned_shm, remove_shm_of_dead
from flexarm_core.goal_sender import own_participant, participant, send_goal_writers, sender_of
from flexarm_core.graph_locks import graph_domain
from flexarm_motion.ros.arm_claim import ArmClaim
from flexarm_msgs.action import CollectSamples, MoveToPose, RefreshModel
from flexarm_msgs.msg import ModelInfo, PlanarPose, TipPose
from flexarm_msgs.srv import Train, UseModel

_ENDED = {GoalStatus.STATUS_CANCELED: 'canceled', GoalStatus.STATUS_ABORTED: 'aborted'}
_SPIN_SLICE = 0.1   # [s] waits spin in slices so that a Ctrl-C is raised at once
SERVER_SILENCE = 3.0  # [s] without an answer from a goal's action server: it is gone
_PROBE_PERIOD = 0.5   # [s] between the watch's requests to the server
CANCEL_WAIT = 5.0     # [s] after Ctrl-C: acceptance, cancel and the cancelled goal's result
# [s] a parameter request unanswered this long is sent again: a server discovered by this
# client may not have discovered the client yet, and drops the request (a DDS service race);
# getting or setting a parameter twice does the same as once.
PARAMETER_RESEND = 1.0


class NamedActionClient(ActionClient):
    """rclpy's action client that says which action it is a client of (Jazzy's keeps the
    name private): the client's messages, probes and discovery checks name it."""

    def __init__(self, node: Node, action_type: Any, action_name: str) -> None:
        super().__init__(node, action_type, action_name)
        self.action_name = action_name


class GoalRejected(RuntimeError):
    """The server rejected the goal before anything moved."""


class GoalFailed(RuntimeError):
    """The goal ended without success and without an error code in its result."""


class ServerLost(GoalFailed):
    """The action server went away while the goal ran: the goal is lost."""


class GoalInterrupted(KeyboardInterrupt):
    """Ctrl-C while a goal ran; the goal was cancelled (if it had been accepted).

    ``accepted``: whether the server accepted the goal (None: no answer in time).
    ``result``: the cancelled goal's result (MoveToPose: ``joint_positions`` where the arm
    stopped), or None when none arrived within ``CANCEL_WAIT``.
    """

    def __init__(self, accepted: bool | None, result: Any = None) -> None:
        super().__init__('interrupted')
        self.accepted, self.result = accepted, result


@dataclass(frozen=True)
class CanceledGoal:
    """A goal :meth:`FlexarmClient.cancel_all` cancelled."""

    action: str          # the action's full name, e.g. /move_to_pose
    goal_id: str         # hex
    result: Any          # its result (status and result), None if none came in time
    sender: str          # who sent it, as the server recorded it ('' if it does not)
    clients: list[str]   # the action's clients now, this one left out


_UNKNOWN = 'unknown node'
ALL_GOALS = UUID(uuid=[0] * 16)   # a cancel request for this id (and stamp 0): every goal


def _known(names: Iterable[str]) -> list[str]:
    """The node names discovery knows already (it reports '_NODE_NAME_UNKNOWN_' until then)."""
    return sorted({n for n in names if n and n != '_NODE_NAME_UNKNOWN_'}) or [_UNKNOWN]


class ServerWatch:
    """Tells whether a goal's action server is still the one that accepted the goal.

    Every ``_PROBE_PERIOD`` it sends the server a cancel request for a goal id nobody has (it
    cancels nothing; a live server answers within milliseconds) and lists the publishers of
    the action's status topic. DDS discovery takes its lease duration (tens of seconds) to
    forget a killed process, so silence is the fast sign of death; a status publisher that
    was not there at acceptance is a restarted server.
    """

    def __init__(self, node: Node, client: NamedActionClient) -> None:
        self._node, self._client = node, client
        self._status_topic = f'{client.action_name}/_action/status'
        self._probe = ClientGoalHandle(client, UUID(uuid=list(uuid.uuid4().bytes)), None)
        self._servers = self._status_publishers()
        self._names = _known(self._servers.values())
        self._pending: Future | None = None
        self._sent = self._answered = time.monotonic()

    def _status_publishers(self) -> dict[bytes, str]:
        return {bytes(info.endpoint_gid): info.node_name for info in
                self._node.get_publishers_info_by_topic(self._status_topic)}

    def lost(self) -> str | None:
        """Why the server is gone, or None while it serves the goal."""
        now = time.monotonic()
        if self._pending is not None and self._pending.done():
            self._answered, self._pending = now, None
        if self._pending is None and now - self._sent >= _PROBE_PERIOD:
            self._pending, self._sent = self._probe.cancel_goal_async(), now
        current = self._status_publishers()
        if not self._servers:            # not discovered at acceptance: the first seen is it
            self._servers = current
        if self._names == [_UNKNOWN] and set(current) <= set(self._servers):
            self._names = _known(current.values())    # names arrive after the endpoints
        server = f'{self._client.action_name} ({", ".join(self._names)})'
        if now - self._answered > liveness.limit(SERVER_SILENCE):
            return (f'{server} stopped answering {now - self._answered:.1f} s ago while the '
                    'goal ran: the node died; the goal is lost')
        if set(current) - set(self._servers):
            return (f'{server} was restarted while the goal ran: the new instance does not '
                    'know the goal; it is lost')
        return None


class GoalRun:
    """A goal sent and running, in nav2_simple_commander's non-blocking shape: poll
    :meth:`done` and :meth:`feedback` from a script's own loop, :meth:`cancel` it, take its
    :meth:`result` (which blocks until it ends). Each call spins the client; none waits longer
    than its timeout or the goal's (``timeout`` at sending, wall clock). Errors are the
    blocking calls': :class:`GoalRejected`, :class:`ServerLost`, :class:`GoalFailed`,
    TimeoutError (the goal is then cancelled), :class:`GoalInterrupted` on Ctrl-C in
    :meth:`result` (cancelled too)."""

    def __init__(self, client: FlexarmClient, action: NamedActionClient, goal: Any, timeout: float,
                 feedback: Callable[[Any], None] | None = None) -> None:
        self._client, self._action, self._timeout = client, action, timeout
        self._deadline = time.monotonic() + timeout
        self._feedback: Any = None
        self._on_feedback = feedback
        if not action.wait_for_server(timeout_sec=min(timeout, 10.0)):
            raise TimeoutError(f'action server {action.action_name} not available')
        client._wait_responsive(action, self._deadline)
        self._sent = action.send_goal_async(goal, feedback_callback=self._feedback_received)
        self._handle: ClientGoalHandle | None = None
        self._result: Future | None = None
        self._watch: ServerWatch | None = None
        client._running = self

    def done(self, spin: float = 0.1) -> bool:
        """Whether the goal has ended; spins the client for up to ``spin`` seconds meanwhile
        (as nav2_simple_commander's ``isTaskComplete``: every callback that comes in that time
        is served, feedback included), less when the goal's next step completes."""
        self._client.serve(self._result if self._result is not None else self._sent, spin)
        if self._handle is None:
            if not self._sent.done():
                return False
            self._accepted(self._sent.result())
        reason = self._watch.lost()
        if reason is not None and not self._result.done():
            raise ServerLost(reason)
        return self._result.done()

    def feedback(self) -> Any:
        """The latest feedback (None before the first)."""
        return self._feedback

    def cancel(self, timeout: float = 10.0) -> None:
        """Cancel the goal and wait (``timeout``) until the server acknowledges it."""
        handle = self._handle or self._accepted(self._client._spin_until(
            self._sent, timeout, 'goal acceptance'))
        self._client._spin_until(handle.cancel_goal_async(), timeout, 'cancel')

    def result(self) -> Any:
        """Wait for the goal's result (module docstring of the errors)."""
        client, name = self._client, self._action.action_name
        try:
            if self._handle is None:
                self._accepted(client._spin_until(self._sent, self._remaining(),
                                                  'goal acceptance'))
            response = client._spin_until(self._result, self._remaining(), 'the result',
                                          self._watch.lost)
        except TimeoutError as exc:
            running = self._handle is not None
            if running:
                self.cancel()
            raise TimeoutError(f'{name}: {exc}' + ('; the goal was cancelled' if running
                                                   else '')) from exc
        except KeyboardInterrupt:   # Ctrl-C, possibly before the acceptance arrived
            end, accepted, ended = time.monotonic() + CANCEL_WAIT, None, None
            with contextlib.suppress(TimeoutError, RuntimeError):   # no answer, or shut down
                handle = client._spin_until(self._sent, end - time.monotonic(),
                                            'goal acceptance')
                accepted = handle.accepted
                if accepted:
                    client._spin_until(handle.cancel_goal_async(), end - time.monotonic(),
                                       'cancel')
                    ended = client._spin_until(self._result or handle.get_result_async(),
                                               end - time.monotonic(), 'the cancelled result')
            raise GoalInterrupted(accepted, None if ended is None else ended.result) from None
        finally:
            if client._running is self:
                client._running = None
        if response.status != GoalStatus.STATUS_SUCCEEDED and response.result.error_code == 0:
            raise GoalFailed(f'{name}: the goal ended '
                             f'{_ENDED.get(response.status, f"in status {response.status}")} '
                             'without an error code (see the server log)')
        return response.result

    def _remaining(self) -> float:
        return self._deadline - time.monotonic()

    def _accepted(self, handle: ClientGoalHandle) -> ClientGoalHandle:
        if not handle.accepted:
            if self._client._running is self:
                self._client._running = None
            raise GoalRejected(f'{self._action.action_name} rejected the goal: the server '
                               'runs one goal at a time and is busy')
        self._handle, self._result = handle, handle.get_result_async()
        self._watch = ServerWatch(self._client, self._action)
        return handle

    def _feedback_received(self, msg: Any) -> None:
        self._feedback = msg.feedback
        if self._on_feedback is not None:
            self._on_feedback(msg.feedback)


class FlexarmClient(Node):
    """Client of the compensator and the learner (of the arm in ``namespace``, '' for a graph
    without one: ``flexarm up --namespace``): each goal blocking, or running as a
    :class:`GoalRun` (``move_async``, ``collect_async``). ``learner_node``: the learner's node
    name, whose parameters (the payload) the client sets (config/graph.yaml names it)."""

    def __init__(self, node_name: str = 'flexarm_client', context: Context | None = None,
                 namespace: str = '', learner_node: str = 'flexarm_learner') -> None:
        self._learner_node = learner_node
        super().__init__(node_name, context=context,
                         namespace=f'/{namespace.strip("/")}' if namespace.strip('/') else '')
        # The ports this process listens on outlive it while a node killed meanwhile mapped
        # them (Fast DDS removes a port with its last user, and a dead process still counts
        # as one): what nobody uses of them goes when the context shuts down.
        self._ports = listened_ports(owned_shm(os.getpid()))
        self.context.on_shutdown(self._remove_unused_ports)
        # The Train client first: see _wait_responsive for why the order matters.
        self._train = self.create_client(Train, topics.TRAIN)
        self._use_model = self.create_client(UseModel, topics.USE_MODEL)
        self._move = NamedActionClient(self, MoveToPose, topics.MOVE_TO_POSE)
        self._collect = NamedActionClient(self, CollectSamples, topics.COLLECT_SAMPLES)
        self._refresh = NamedActionClient(self, RefreshModel, topics.REFRESH_MODEL)
        self._arm = ArmClaim(self, self._waited)
        self._executor = SingleThreadedExecutor(context=self.context)
        self._serving = threading.Lock()     # one thread at a time in the executor (serve)
        # One per node, made on first use; its service clients go with destroy_node.
        self._parameter_clients: dict[str, AsyncParameterClient] = {}
        self._executor.add_node(self)
        self._running: GoalRun | None = None     # the goal this client sent last, running
        self.active_model: ModelInfo | None = None
        latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
        self.create_subscription(ModelInfo, topics.ACTIVE_MODEL,
                                 lambda msg: setattr(self, 'active_model', msg), latched)


    def _remove_unused_ports(self) -> None:
        remove_shm_of_dead(self._ports)
    def wait_until_ready(self, timeout: float = 30.0, learner: bool = True,
                         compensator: bool = True) -> None:
        """Wait until the compensator's and/or the learner's servers answer this client.

        TimeoutError names this client's ROS domain, what is missing and the likely cause."""
        deadline = time.monotonic() + timeout
        domain = f'ROS_DOMAIN_ID={self.context.get_domain_id()}'
        waits: list[tuple[str, Callable[[float], bool]]] = []
        if compensator:
            waits.append((topics.MOVE_TO_POSE, self._move.wait_for_server))
        if learner:
            waits += [(topics.COLLECT_SAMPLES, self._collect.wait_for_server),
                      (topics.TRAIN, self._train.wait_for_service)]
        for name, wait in waits:
            if not wait(max(0.0, deadline - time.monotonic())):
                raise TimeoutError(
                    f'no flexarm graph in {domain} after {timeout:.3g} s '
                    f'({topics.absolute(name, self.get_namespace())} not found): start one '
                    'with `flexarm up`, or pass the domain (--domain-id) and namespace '
                    '(--namespace) of a running one')
        for wanted, client in ((compensator, self._move), (learner, self._collect)):
            if wanted:
                try:
                    self._wait_responsive(client, deadline)
                except TimeoutError as exc:
                    raise TimeoutError(f'{exc} in {domain} after {timeout:.3g} s: its node is '
                                       'discovered but hangs or is overloaded (see its log)'
                                       ) from exc

    def move_async(self, x: float, y: float, phi: float, mode: str = 'predictive', *,
                   position_tolerance: float = 0.0, angle_tolerance: float = 0.0,
                   max_corrections: int = 0, trial: str = '', timeout: float = 300.0,
                   allow_extrapolation: bool = False, dry_run: bool = False,
                   feedback: Callable[[MoveToPose.Feedback], None] | None = None,
                   motion: str = '') -> GoalRun:
        """Send a MoveToPose goal and return at once: poll the :class:`GoalRun` (``done``,
        ``feedback``), ``cancel`` it, take its ``result`` (``allow_extrapolation``: run a
        PREDICTIVE goal beyond the learned data with a warning instead of its refusal;
        ``dry_run``: only plan, the result holds the plan and nothing moves; ``motion``: run
        within this client's claim of the arm, :meth:`claimed_arm`)."""
        goal = MoveToPose.Goal(target=PlanarPose(x=float(x), y=float(y), phi=float(phi)),
                               mode=int(Mode.of(mode)),
                               position_tolerance=float(position_tolerance),
                               angle_tolerance=float(angle_tolerance),
                               max_corrections=int(max_corrections), trial=trial,
                               allow_extrapolation=bool(allow_extrapolation),
                               dry_run=bool(dry_run), motion=motion)
        return GoalRun(self, self._move, goal, timeout, feedback)

    def move_to(self, x: float, y: float, phi: float, mode: str = 'predictive',
                **options: Any) -> MoveToPose.Result:
        """:meth:`move_async` (same arguments) and wait for its result."""
        return self.move_async(x, y, phi, mode, **options).result()

    def collect_async(self, count: int, region: str = '', strategy: str = '', seed: int = 0,
                      dataset: str = '', timeout: float = 3600.0,
                      feedback: Callable[[CollectSamples.Feedback], None] | None = None,
                      ) -> GoalRun:
        """Start collecting ``count`` deflection samples; the running :class:`GoalRun`."""
        goal = CollectSamples.Goal(count=int(count), region=region, strategy=strategy,
                                   seed=int(seed), dataset=dataset)
        return GoalRun(self, self._collect, goal, timeout, feedback)

    def collect(self, count: int, region: str = '', **options: Any) -> CollectSamples.Result:
        """:meth:`collect_async` (same arguments) and wait for its result."""
        return self.collect_async(count, region, **options).result()

    def refresh(self, count: int = 0, region: str = '', timeout: float = 1800.0,
                feedback: Callable[[RefreshModel.Feedback], None] | None = None,
                force: bool = False) -> RefreshModel.Result:
        """Refresh the current model from ``count`` new samples (0: the learner's default) in
        ``region`` ('': the regions the model health reports stale; ``force``: even where the
        model health sees it fit) and wait for the result."""
        goal = RefreshModel.Goal(count=int(count), region=region, force=force)
        return GoalRun(self, self._refresh, goal, timeout, feedback).result()

    def set_payload(self, kg: float, timeout: float = 10.0) -> None:
        """Declare the payload [kg] the arm carries now (the learner's ``payload``, published
        on /payload for the compensator and the simulator)."""
        self.set_node_parameter(self._learner_node, 'payload', float(kg), timeout)

    def train(self, kind: str = '', settings: Mapping[str, Any] | None = None,
              dataset: str = '', timeout: float = 120.0) -> Train.Response:
        """Train a predictor (``kind`` '': the learner's default) on a dataset; the response
        carries the validation metrics and the samples excluded as outliers."""
        if not self._train.wait_for_service(timeout_sec=min(timeout, 10.0)):
            raise TimeoutError(f'{topics.TRAIN} not available')
        request = Train.Request(kind=kind, settings_json=json.dumps(dict(settings or {})),
                                dataset=dataset)
        return self._spin_until(self._train.call_async(request), timeout, 'training')

    def use_model(self, version: str, timeout: float = 30.0) -> UseModel.Response:
        """Make the model ``version`` current again (roll back); the learner checks and
        announces it. The compensator has switched once :meth:`wait_for_model` returns."""
        if not self._use_model.wait_for_service(timeout_sec=min(timeout, 10.0)):
            raise TimeoutError(f'{topics.USE_MODEL} not available: is the learner running?')
        request = UseModel.Request(version=str(version))
        return self._spin_until(self._use_model.call_async(request), timeout, 'model change')

    def wait_for_model(self, version: str, timeout: float = 30.0) -> ModelInfo:
        """Wait until the compensator uses the model ``version`` (after :meth:`train`)."""
        deadline = time.monotonic() + timeout
        while self.active_model is None or self.active_model.version != version:
            if time.monotonic() > deadline:
                have = self.active_model.version if self.active_model else 'none'
                raise TimeoutError(f'compensator still uses model {have}, not {version}, '
                                   f'after {timeout:.0f} s')
            self.spin_once(0.05)
        return self.active_model

    def poses_from(self, topic: str, count: int, timeout: float = 10.0) -> np.ndarray:
        """``count`` valid ``flexarm_msgs/TipPose`` poses (count, 3) published on ``topic``
        after this call (e.g. a reference instrument's); TimeoutError if they do not come."""
        heard = self.messages_from(topic, TipPose, count, timeout, lambda m: m.valid,
                                   what='valid poses')
        return np.array([[m.pose.x, m.pose.y, m.pose.phi] for m in heard])

    def messages_from(self, topic: str, msg_type: type, count: int, timeout: float = 10.0,
                      accept: Callable[[Any], bool] = lambda _: True, qos: Any = 100,
                      what: str = 'messages') -> list[Any]:
        """The first ``count`` messages on ``topic`` after this call that ``accept`` takes;
        TimeoutError naming ``what`` if they do not come within ``timeout`` seconds."""
        heard: list[Any] = []
        subscription = self.create_subscription(
            msg_type, topic, lambda m: heard.append(m) if accept(m) else None, qos)
        try:
            deadline = time.monotonic() + timeout
            while len(heard) < count:
                if time.monotonic() > deadline:
                    raise TimeoutError(f'{count} {what} on {topic} did not come within '
                                       f'{timeout:.0f} s')
                self.spin_once(0.05)
        finally:
            self.destroy_subscription(subscription)
        return heard[:count]

    def node_parameter(self, node: str, name: str, timeout: float = 10.0) -> Any:
        """The value of parameter ``name`` of the graph's node ``node``."""
        values = self._parameter_call(
            node, lambda client: client.get_parameters([name]), timeout,
            f'{node} parameter {name}').values
        return parameter_value_to_python(values[0])

    def node_parameters(self, node: str, names: Iterable[str] | None = None,
                        timeout: float = 10.0) -> dict[str, Any]:
        """Parameters of the graph's node ``node`` by name (``names``; all it has if None):
        their values, None for a name it does not have (rclpy leaves such a name out of its
        answer: then the names it has are asked for first)."""
        def listed() -> list[str]:
            return self._parameter_call(node, lambda client: client.list_parameters(),
                                        timeout, f'{node} parameter names').result.names

        def values(asked: list[str]) -> list[Any]:
            return self._parameter_call(node, lambda client: client.get_parameters(asked),
                                        timeout, f'{node} parameters').values

        wanted = asked = sorted(listed() if names is None else names)
        answer = values(asked)
        if len(answer) != len(asked):
            asked = sorted(set(wanted) & set(listed()))
            answer = values(asked)
        found = dict(zip(asked, map(parameter_value_to_python, answer)))
        return {name: found.get(name) for name in wanted}

    def describe_node_parameter(self, node: str, name: str,
                                timeout: float = 10.0) -> dict[str, Any] | None:
        """Parameter ``name`` of the graph's node ``node`` as it describes it: its ``name``,
        ``type`` (as the params files' schema names it: ``double``, ``string_array``),
        ``description`` (unit first), ``range`` ([low, high], None without one) and
        ``read_only``; None for a name it does not have (rclpy answers no descriptor)."""
        descriptors = self._parameter_call(
            node, lambda client: client.describe_parameters([name]), timeout,
            f'{node} parameter {name} description').descriptors
        if not descriptors:
            return None
        described = descriptors[0]
        bounds = [*described.integer_range, *described.floating_point_range]
        return {'name': described.name, 'type': Parameter.Type(described.type).name.lower(),
                'description': described.description,
                'range': [bounds[0].from_value, bounds[0].to_value] if bounds else None,
                'read_only': described.read_only}

    def set_node_parameter(self, node: str, name: str, value: Any,
                           timeout: float = 10.0, kind: Parameter.Type | None = None) -> None:
        """Set parameter ``name`` of the graph's node ``node`` (as a ``kind`` value, else of
        the kind of ``value``); ValueError with the node's reason if it refuses."""
        parameter = Parameter(name, kind, value) if kind is not None else Parameter(
            name, value=value)
        result = self._parameter_call(
            node, lambda client: client.set_parameters([parameter]),
            timeout, f'{node} parameter {name}').results[0]
        if not result.successful:
            raise ValueError(f'{node} refused {name}: {result.reason}')

    def _parameter_call(self, node: str, request: Callable[[AsyncParameterClient], Future],
                        timeout: float, what: str) -> Any:
        """The response to ``request`` of ``node``'s parameter services, sent again every
        ``PARAMETER_RESEND`` s until it is answered or ``timeout`` runs out."""
        deadline = time.monotonic() + timeout
        client = self._parameter_clients.get(node)
        if client is None:
            client = self._parameter_clients[node] = AsyncParameterClient(self, node)
        if not client.wait_for_services(timeout):
            raise TimeoutError(f'no parameter services of {node} within {timeout:.0f} s')
        while True:
            future = request(client)
            remaining = deadline - time.monotonic()
            try:
                return self._spin_until(future, min(remaining, PARAMETER_RESEND), what)
            except TimeoutError:
                future.cancel()
                if remaining <= PARAMETER_RESEND:
                    raise TimeoutError(f'timed out after {timeout:.1f} s waiting for '
                                       f'{what}') from None

    def claimed_arm(self, kind: str, description: str) -> contextlib.AbstractContextManager[str]:
        """Hold the arm across several goals (a calibration): the motion id to send them
        ``within`` (``move_async(..., motion=id)``); :class:`ArmBusy` naming the motion that
        holds it. While held, no other motion moves the arm; :meth:`arm_held` tells whether
        the claim still holds (``flexarm cancel`` ends it)."""
        return self._arm.claimed(kind, description)

    def arm_held(self) -> str:
        """'' while this client's claim holds the arm, else why not."""
        return '' if self._arm.holds() else (self._arm.lost or 'this client holds no claim')

    def end_motion(self) -> str:
        """End whichever motion holds the arm (force: ``flexarm cancel``); what was ended, ''
        if the arm was free."""
        released = self._arm.release(force=True)
        return released if released.startswith('ended') else ''

    def spin_once(self, timeout: float) -> None:
        """Process this client's pending callbacks for up to ``timeout`` seconds."""
        self.serve(None, timeout)

    def serve(self, future: Future | None, timeout: float) -> None:
        """Serve this client's callbacks for up to ``timeout`` s, less once ``future`` is done
        (None: one callback), one thread at a time: a goal waited for in one thread and a
        cancel sent from another (a stop button) take turns in the executor, whose callbacks
        complete either's futures, instead of entering it together (rclpy raises "generator
        already executing")."""
        with self._serving:
            if future is None:
                self._executor.spin_once(timeout_sec=timeout)
            else:
                self._executor.spin_until_future_complete(future, timeout_sec=timeout)

    def cancel(self, timeout: float = 10.0) -> None:
        """Cancel the goal in progress (if any) and wait for the server to acknowledge."""
        if self._running is not None:
            self._running.cancel(timeout)

    def cancel_all(self, timeout: float = 10.0) -> list[CanceledGoal]:
        """Cancel every goal that runs on the arm's action servers (MoveToPose, and
        CollectSamples and RefreshModel when the learner serves them), whoever sent them, and
        wait (bounded by ``CANCEL_WAIT``) for their results. Call after
        :meth:`wait_until_ready` (``learner=False`` is enough: the learner's servers are
        waited for when discovery knows the learner)."""
        deadline = time.monotonic() + timeout
        learner = (self._learner_node, self.get_namespace()) in \
            self.get_node_names_and_namespaces()
        canceled = []
        for client in (self._move, self._collect, self._refresh):
            if not client.server_is_ready() and not (learner and client.wait_for_server(
                    timeout_sec=max(0.0, deadline - time.monotonic()))):
                continue
            self._wait_responsive(client, deadline)
            response = self._spin_until(
                ClientGoalHandle(client, ALL_GOALS, None).cancel_goal_async(),
                deadline - time.monotonic(), f'the cancel of {client.action_name}')
            action = topics.absolute(client.action_name, self.get_namespace())
            writers = send_goal_writers(self, action)
            me = own_participant(writers, topics.absolute(self.get_name(),
                                                          self.get_namespace()), os.getpid())
            clients = sorted({name for gid, name in writers if participant(gid) != me})
            for info in response.goals_canceling:
                future = ClientGoalHandle(client, info.goal_id, None).get_result_async()
                with contextlib.suppress(TimeoutError):
                    self._spin_until(future, CANCEL_WAIT, 'the cancelled result')
                result = future.result() if future.done() else None
                canceled.append(CanceledGoal(
                    action, bytes(info.goal_id.uuid).hex(), result,
                    sender_of(result.result.error_string) if result is not None else '',
                    clients))
        return canceled

    def destroy_node(self) -> None:
        self._move.destroy()
        self._collect.destroy()
        self._refresh.destroy()
        self._executor.shutdown(timeout_sec=1.0)
        super().destroy_node()

    def _wait_responsive(self, client: NamedActionClient, deadline: float) -> None:
        """Wait until the action server has answered a request of this client.

        ``wait_for_server`` only means that this client sees the server's request readers.
        With Fast DDS a response sent before the server has discovered this client's reply
        readers is dropped ("Failed to send goal response"), and with it the goal, which then
        never starts while the client waits for its acceptance. The probe is a cancel request
        for a goal id nobody has (it cancels nothing), repeated until one is answered. Reply
        readers are announced in the order they were created: the cancel service's comes
        after the goal service's of the same action and after the Train client's (created
        first), so an answered probe means those have been discovered too. An answer to any
        probe counts: a server that answers each more than a second late (a loaded machine)
        answers the earlier ones while this client waits for the latest.
        """
        probe = ClientGoalHandle(client, UUID(uuid=list(uuid.uuid4().bytes)), None)
        answered = Future()

        def count(_: Future) -> None:
            if not answered.done():
                answered.set_result(True)

        while not answered.done():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f'action server {client.action_name} does not answer')
            probe.cancel_goal_async().add_done_callback(count)
            self.serve(answered, min(1.0, remaining))

    def _waited(self, future: Future, timeout: float) -> bool:
        try:
            self._spin_until(future, timeout, 'the arm owner')
        except TimeoutError:
            return False
        return True

    def _spin_until(self, future: Future, timeout: float, what: str,
                    lost: Callable[[], str | None] = lambda: None) -> Any:
        """The future's result; TimeoutError after ``timeout``, ServerLost when ``lost`` says
        why the server went away."""
        deadline = time.monotonic() + timeout
        while not future.done():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f'timed out after {timeout:.1f} s waiting for {what}')
            if not self.context.ok():
                raise RuntimeError(f'ROS was shut down while waiting for {what}')
            reason = lost()
            if reason is not None:
                raise ServerLost(reason)
            self.serve(future, min(remaining, _SPIN_SLICE))
        return future.result()


def init_client(domain_id: int | None = None, namespace: str = '',
                learner_node: str = 'flexarm_learner',
                say: Callable[[str], None] | None = None) -> FlexarmClient:
    """Initialise rclpy (default context, SIGINT left to Python) and create a client node (of
    the arm in ``namespace``), as the ``flexarm`` commands do:

    * transports confined to this machine unless the environment widens them
      (``ROS_AUTOMATIC_DISCOVERY_RANGE`` LOCALHOST by default, :mod:`flexarm_core.transport`);
    * without ``domain_id`` and without an exported ``ROS_DOMAIN_ID``, the domain of the one
      flexarm graph running on this machine (:func:`flexarm_core.graph_locks.graph_domain`;
      ``flexarm up`` takes the first free domain), said through ``say`` (default: the client's
      logger); :class:`~flexarm_core.graph_locks.SeveralGraphs` when several could be meant.
    """
    os.environ.setdefault(transport.RANGE_ENV, 'LOCALHOST')
    transport.apply(os.environ)      # before the process's first participant: read once
    note = ''
    if domain_id is None:
        domain_id, note = graph_domain(namespace, os.environ)
    rclpy.init(domain_id=domain_id, signal_handler_options=rclpy.SignalHandlerOptions.NO)
    client = FlexarmClient(namespace=namespace, learner_node=learner_node)
    if note:
        (say or client.get_logger().info)(note)
    return client
