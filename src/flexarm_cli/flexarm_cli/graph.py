"""``flexarm up``, ``ps``, ``down`` and ``status``: starting, listing, stopping and reading a
graph."""
from __future__ import annotations

import argparse
import contextlib
import os
import re
import signal
import threading
from types import FrameType
from typing import TYPE_CHECKING, Any

from flexarm_bringup.launcher import node_name
from flexarm_cli.common import Outcome, graph_client, timed_step, usage, world_settings
from flexarm_core import transport
from flexarm_core.paths import RUNS_DIR
from flexarm_recording.results.outcome_text import (
    Exit,
)

if TYPE_CHECKING:     # imported where used: the other commands start without them
    from flexarm_bringup.graph_watch import FirstReports
    from flexarm_bringup.supervisor import Graph

_GENERATED_MESSAGE = re.compile(r'[/\\](?:msg|srv|action)[/\\]_\w+\.py$')   # rosidl's Python


_RESIGNAL = 0.005         # [s] until a signal that came during a message conversion is resent


def cmd_up(args: argparse.Namespace) -> dict[str, Any]:
    """Start the graph (one process per node), wait until ready, supervise until stopped."""
    import time

    from flexarm_bringup import supervisor
    from flexarm_bringup.graph_watch import FirstReports, GraphWatch
    from flexarm_bringup.supervisor import Graph
    from flexarm_bringup.up_domain import DomainRefused, claim_domain
    from flexarm_core.graph_locks import LOCK_DIR, running_graphs

    if args.link_key and not os.path.isfile(args.link_key):
        raise usage(f'no key file {args.link_key} (make one with flexarm keygen FILE)')
    name = args.name or time.strftime('up-%Y%m%d-%H%M%S') + (
        f'-{args.namespace.replace("/", "-")}' if args.namespace else '')
    params, optional = _up_parameters(args)
    discovery = _up_transport(args)
    try:
        supervisor.graph_specs(args.robot, optional, args.only)     # arguments first
        claim = claim_domain(args.domain_id, os.environ, args.namespace,
                             lambda: running_graphs(LOCK_DIR, RUNS_DIR))
    except (ValueError, DomainRefused) as exc:
        raise usage(str(exc)) from None
    domain = claim.domain_id
    with claim.reservation or contextlib.nullcontext():
        try:
            graph = Graph(domain, RUNS_DIR / name, robot=args.robot, parameters=params,
                          optional=optional, discovery=discovery, namespace=args.namespace,
                          only=args.only)
        except ValueError as exc:
            raise usage(str(exc)) from None
        started, ready = time.monotonic(), None
        print(f'starting {", ".join(graph.nodes)} in ROS_DOMAIN_ID={domain} ({claim.how}); '
              f'logs in {graph.run_dir}', flush=True)
        if graph.remote:
            print(_remote_text(graph.remote, discovery), flush=True)
        reports = FirstReports(lambda: GraphWatch(domain, args.namespace),
                               lambda line: print(line, flush=True))
        hangup = _bind_lifetime(args.outlive_parent)
        try:
            graph.start()
            graph.wait_ready(args.timeout)
            ready = time.monotonic() - started
            _supervise(graph, reports, args, domain, ready)
        except KeyboardInterrupt:
            pass
        finally:
            reports.close()
            codes = graph.stop()
            if hangup:
                signal.signal(signal.SIGHUP, signal.SIG_DFL)
            print('stopped: ' + ', '.join(f'{n} ({c})' for n, c in codes.items()), flush=True)
    return {'ok': True, 'domain_id': domain, 'domain_chosen': claim.how, 'exit_codes': codes,
            'run_dir': str(graph.run_dir)}


def _up_parameters(args: argparse.Namespace) -> tuple[dict[str, dict[str, Any]], tuple[str, ...]]:
    """The run's parameters over graph.yaml's (simulated world, link key, recording, Foxglove)
    and the optional nodes it starts."""
    simulated = {**({} if args.rtf is None else {'real_time_factor': args.rtf}),
                 **world_settings(args)}
    link = {'link_key_file': os.path.abspath(args.link_key)} if args.link_key else {}
    params: dict[str, dict[str, Any]] = {node_name('simulator'): simulated,
                                         node_name('fake_controller'): simulated | link,
                                         node_name('bridge'): link}
    if args.record:
        params[node_name('recorder')] = {'bag_name': args.record,
                                         'record_images': args.record_images}
    if args.foxglove:
        params[node_name('foxglove')] = {'port': args.foxglove}
    optional = ((node_name('recorder'),) if args.record else ()) + (
        (node_name('foxglove'),) if args.foxglove is not None else ())
    return params, optional


def _up_transport(args: argparse.Namespace) -> str:
    """Apply the discovery range and transports every participant of up shares (its own
    readiness checks too); the range, in the environment's spelling."""
    discovery = args.discovery.upper()
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = discovery
    transport.apply(os.environ)
    unusable = transport.profile_problem(os.environ)
    if unusable:
        raise usage(unusable)
    exposure = transport.warning(os.environ)
    if exposure:
        print(exposure, flush=True)
    return discovery


def _supervise(graph: Graph, reports: FirstReports, args: argparse.Namespace, domain: int,
               ready: float) -> None:
    """Say the graph is ready and what it started with, then watch it until interrupted: a
    death, an ERROR in a (re)started node's reports."""
    from flexarm_core import liveness

    arm = f' --namespace {args.namespace}' if args.namespace else ''
    print(f'graph ready in {ready:.1f} s. In another shell: ROS_DOMAIN_ID={domain} '
          f'flexarm move 1450 -150 -45{arm}. Ctrl-C stops '
          f'{"the nodes of this host" if graph.remote else "everything"}'
          f'{"" if args.outlive_parent else LIFETIME_TEXT}.', flush=True)
    watch = reports.expect(graph.nodes, liveness.limit(REPORT_WAIT))
    print(_starting_model(watch), flush=True)
    if node_name('vision') in graph.nodes:
        print(_calibration(watch), flush=True)
    if args.foxglove is not None:
        print(foxglove_served(graph.nodes[node_name('foxglove')],
                              liveness.limit(FOXGLOVE_WAIT)), flush=True)
    while True:
        reports.step(0.5)
        restarted = [n for n in graph.check() if not graph.nodes[n].reported]
        if restarted:
            reports.expect(restarted, liveness.limit(RESTART_REPORT_WAIT))


LIFETIME_TEXT = ', and so does the end of the process that started this one (--outlive-parent)'


# [s, wall; liveness-scaled] for the first /diagnostics report of a node of a ready graph, of a
# restarted one (it imports, starts and is discovered first)
REPORT_WAIT = 5.0


RESTART_REPORT_WAIT = 20.0


# [s, wall; liveness-scaled] for the Foxglove node of a ready graph to say that its server
# listens (it is discovered, so the graph is ready, before it makes the server)
FOXGLOVE_WAIT = 10.0


def _bind_lifetime(outlive_parent: bool) -> bool:
    """Tie ``up`` (and so its graph) to what started it, unless ``outlive_parent``: the kernel
    sends SIGTERM when the starting process (thread) ends, a harness killed at its time budget
    included, and SIGTERM stops the graph as Ctrl-C does. Under init or a service manager that
    changes nothing (the parent outlives the service). A hang-up (the terminal closed) stops it
    too, unless ignored (``nohup``). Whether SIGHUP's handler was set (to undo at the end)."""
    from flexarm_core.parent_death import signal_on_parent_death

    signal_on_parent_death(0 if outlive_parent else signal.SIGTERM)
    if signal.getsignal(signal.SIGHUP) != signal.SIG_DFL:
        return False
    signal.signal(signal.SIGHUP, interrupt_handler)   # the default ends the process without a stop
    return True


def _remote_text(remote: tuple[str, ...], discovery: str) -> str:
    """What `up --only` expects from the other hosts, and whether DDS can reach them."""
    text = f'the rest of the graph must run on other hosts: {", ".join(remote)}'
    if not transport.exposed(os.environ | {transport.RANGE_ENV: discovery}):
        text += ('; but DDS discovery stays on this machine: use --discovery subnet or set '
                 'ROS_STATIC_PEERS to the other hosts')
    return text


def foxglove_served(node: Any, within: float) -> str:
    """Where Foxglove connects, once the Foxglove node (a :class:`NodeProcess`) has said in its
    log that its server listens (the URL it said), or why it is not said: the node died, or
    did not say so ``within`` seconds."""
    import time

    from flexarm_viz.foxglove_node import listening_url

    deadline = time.monotonic() + within
    while True:
        pid = node.process.pid
        try:
            url = listening_url(node.log_path.read_text(errors='replace'), pid)
        except OSError:
            url = None
        if url is not None:
            return foxglove_text(url)
        if node.returncode is not None or time.monotonic() > deadline:
            why = ('exited' if node.returncode is not None
                   else f'has not said that it listens after {within:.0f} s')
            return f'Foxglove: not served: {node.spec.name} {why} (log: {node.log_path})'
        time.sleep(0.05)


def foxglove_text(url: str) -> str:
    """Where Foxglove connects (the server's URL) and which layout."""
    from flexarm_core.params import config_path

    return (f'Foxglove: open a connection to {url} (Foxglove WebSocket) and import the '
            f'layout {config_path("foxglove_layout.json")}')


def _starting_model(watch: Any, listen: float = 3.0) -> str:
    """Which model the compensator of a just-started graph runs (it loads the learner's
    current one within a moment of start-up), or why there is none."""
    from flexarm_bringup.graph_status import model_summary
    from flexarm_bringup.status_text import starting_model_text
    from flexarm_core import liveness

    def learner() -> Any:
        return watch.statuses.get('flexarm_learner: model')

    watch.spin(liveness.limit(listen), until=lambda: watch.active_model is not None
               or starting_model_text(None, learner()) is not None)
    return (starting_model_text(model_summary(watch.active_model), learner())
            or 'model driving the arm: none yet (the compensator has loaded none so far)')


def _calibration(watch: Any, listen: float = 3.0) -> str:
    """Whether the camera of a just-started graph is calibrated (its vision node's first
    report)."""
    from flexarm_bringup.graph_status import calibration_status_name
    from flexarm_bringup.status_text import calibration_text
    from flexarm_core import liveness

    watch.spin(liveness.limit(listen), until=lambda: calibration_status_name() in watch.statuses)
    return calibration_text(watch.statuses.get(calibration_status_name()))


def interrupt_handler(signum: int, frame: FrameType | None) -> None:
    """SIGINT/SIGTERM: raise KeyboardInterrupt, so that a running goal is cancelled.

    Never while rclpy converts a ROS message (Python code of a generated message module
    called from its C++ layer): there pybind11 would turn the exception into a RuntimeError
    ('Unable to convert call argument') and the goal would run on. The signal is sent again
    ``_RESIGNAL`` later instead (a conversion takes microseconds)."""
    while frame is not None:
        if _GENERATED_MESSAGE.search(frame.f_code.co_filename):
            threading.Timer(_RESIGNAL, os.kill, (os.getpid(), signum)).start()
            return
        frame = frame.f_back
    raise KeyboardInterrupt


def cmd_rehearse(args: argparse.Namespace) -> dict[str, Any]:
    """Play a site's controller and tip camera on this machine, on wall time (graph.yaml's
    rehearsal programs: the simulated arm behind the controller protocol), until Ctrl-C; then
    flexarm up --robot bridge in the same domain drives it as it would the real arm."""
    import time
    from datetime import datetime

    from flexarm_bringup.launcher import (
        NodeProcess,
        load_rehearsal,
        ros_env,
        stop_all,
    )

    domain = args.domain_id if args.domain_id is not None else os.environ.get('ROS_DOMAIN_ID')
    if domain is None or str(domain).strip() == '':
        raise usage('--domain-id N: the ROS domain that `flexarm up --robot bridge` runs in (or '
                    'export ROS_DOMAIN_ID in both shells)')
    run_dir = RUNS_DIR / f'rehearse-{datetime.now():%Y%m%d-%H%M%S}'
    nodes = [NodeProcess(spec, ros_env(int(domain), run_dir / 'ros_log'),
                         run_dir / f'{spec.name}.log', None, args.namespace)
             for spec in load_rehearsal()]
    for node in nodes:
        node.start()
    print(f'rehearsing {", ".join(n.spec.name for n in nodes)} in ROS_DOMAIN_ID={domain} on '
          f'wall time; logs in {run_dir}; Ctrl-C stops', flush=True)
    try:
        while all(node.returncode is None for node in nodes):
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    codes = stop_all(nodes)
    print('stopped: ' + ', '.join(f'{name} ({code})' for name, code in codes.items()))
    return {'ok': True, 'domain_id': int(domain), 'run_dir': str(run_dir), 'exit_codes': codes}


def cmd_ps(args: argparse.Namespace) -> dict[str, Any]:
    """List the flexarm graphs running on this machine: domain, namespace, supervisor, robot."""
    from flexarm_bringup.running_graphs import graph_table
    from flexarm_core.graph_locks import LOCK_DIR, running_graphs

    graphs = running_graphs(LOCK_DIR, RUNS_DIR)
    print(graph_table(graphs) if graphs else 'no flexarm graph runs on this machine')
    return {'ok': True, 'graphs': [g.as_dict() for g in graphs]}


def cmd_down(args: argparse.Namespace) -> dict[str, Any]:
    """Stop a graph of this machine (as Ctrl-C in its shell) and wait until it has ended."""
    from flexarm_bringup.running_graphs import (
        AmbiguousGraph,
        NoSuchGraph,
        select,
        stop,
    )
    from flexarm_core.graph_locks import LOCK_DIR, running_graphs

    try:
        graph = select(running_graphs(LOCK_DIR, RUNS_DIR), args.domain_id,
                       args.namespace)
    except NoSuchGraph as exc:
        raise Outcome(str(exc), Exit.NO_GRAPH) from None
    except AmbiguousGraph as exc:
        raise usage(str(exc)) from None
    what = f'the graph in ROS domain {graph.domain_id}' + (
        f' with namespace {graph.namespace}' if graph.namespace else '')
    with timed_step(f'stopping {what} (supervisor pid {graph.supervisor_pid})', args):
        ended = stop(graph, args.timeout)
    fields = {'graph': graph.as_dict()}
    if not ended:
        raise Outcome(f'{what} is still stopping after {args.timeout:g} s (supervisor pid '
                      f'{graph.supervisor_pid}); see flexarm ps', Exit.FAILED, **fields)
    print(f'stopped {what} (supervisor pid {graph.supervisor_pid})')
    return {'ok': True, **fields}


def cmd_status(args: argparse.Namespace) -> dict[str, Any]:
    """What runs in the domain, which model drives the arm, and what is wrong (exit 5)."""
    import rclpy

    from flexarm_bringup.graph_status import (
        graph_problems,
        query,
        supervisor_record,
    )
    from flexarm_bringup.status_text import status_text

    client = graph_client(args, node_name('learner'))
    try:
        record = supervisor_record(RUNS_DIR, client.context.get_domain_id(), args.namespace)
        with timed_step('asking the graph', args):
            status = query(client, args.namespace, record)
    finally:
        client.destroy_node()
        rclpy.try_shutdown()
    silent = status['controller'] if not status['joint_state_rate_hz'] else None
    status['problems'] = graph_problems(status['errors'], record, silent_controller=silent)
    print(status_text(status, record))
    status['supervisor'] = record
    if not any(status['nodes'].values()):
        where = f'ROS_DOMAIN_ID={status["domain_id"]}'
        if status['arms']:      # arms under other namespaces
            arms = ', '.join(arm or '(no namespace)' for arm in status['arms'])
            arm = f'under /{args.namespace}' if args.namespace else 'without namespace'
            raise Outcome(f'no flexarm graph in {where} {arm}; the domain runs the arm(s) '
                          f'{arms}: pass --namespace NS', Exit.NO_GRAPH, **status)
        raise Outcome(f'no flexarm graph in {where}: start one with `flexarm up`, or pass '
                      '--domain-id', Exit.NO_GRAPH, **status)
    if status['problems']:
        raise Outcome(f'the graph has {len(status["problems"])} problem(s): see PROBLEMS above',
                      Exit.DEGRADED, **status)
    return {'ok': True, **status}
