"""Every node of the graph started, made busy and stopped, many times: does any crash on its
way out?

Starts the default graph of ``flexarm up`` at x10 real time with the recorder (so every
stream is watched and the state publisher, the scene and the vision node are at work), and a
client that keeps the learner and the compensator busy the whole time: collections, trainings
(the training worker runs while a node is stopped) and goals of every mode. Then, ``--cycles``
times, each node in turn is stopped with SIGINT or SIGTERM (alternately) at a random moment of
its work, its exit code read, and it is started again; the next stop waits until the node is
back in the graph (discovered) and has run for a random while. The graph's own stop at the end
(every node at once, as ``flexarm down`` and Ctrl-C do) is judged too.

``--graph-stops N``: then, N times, a fresh graph is brought up, made busy, one node of it
killed with SIGKILL every other time (a node that crashed, or a test's kill: the others stop
while the dead participant is still in their discovery), and the whole graph stopped at once
with SIGINT; every node signalled is judged. Such a stop is when the segmentation faults in
``destroy_node`` were seen (tests/test_graph.py kills two nodes, then stops the graph).

``crashes``: exits with a non-zero code or by a signal other than the one sent (a segmentation
fault, an abort). ``signal_exits``: exits by the very signal sent — the node did not handle it
(killed while it was still importing; counted apart, not a crash). A node that did not end
within ``--stop-wait`` seconds (liveness-scaled) is killed and counted in ``hung``.

    python tests/endurance/lifecycle.py [--cycles 100] [--minutes M] [--nodes sim,...]
                                        [--graph-stops N] [--json]
    python tests/endurance/lifecycle.py --cycles 1 --nodes state_publisher --json     (smoke)

JSON (last line): ``crashes``, ``hung``, ``signal_exits``, ``cycles`` (done within
``--minutes``), ``stops``, ``graph_stops`` (whole-graph stops judged, the end of the cycles'
graph included), ``per_node`` (per node ``stops``, ``crashes``, ``codes``: exit code ->
count, every stop counted), ``crash_logs`` (the last lines of each crashed node's log, at
most five), ``busy_goals`` (goals the client ran meanwhile),
``wall_s``.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import random
import signal
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

import rclpy
from rclpy.context import Context

from flexarm_bringup.launcher import NodeProcess, node_name
from flexarm_bringup.supervisor import Graph
from flexarm_cli.experiment import reserved_domain
from flexarm_control.ros.client import FlexarmClient, GoalFailed
from flexarm_core import liveness

READY_S = 120.0          # [s] bound of the graph's bring-up
BACK_S = 60.0            # [s] bound of a restarted node's return to the graph
ROLES = ('simulator', 'vision', 'learner', 'compensator', 'state_publisher', 'scene',
         'recorder')
# Table 10's B1 target and a nearby one: goals the busy client alternates between [m, rad]
FIRST_SAMPLES = 8        # the fewest a training takes
TARGETS = ((1.3, -0.5, -0.35), (1.25, -0.55, -0.3))


class Busy:
    """A client that keeps the learner and the compensator at work until stopped: collect a
    few samples, train, then goals of every mode; every failure (a node being stopped under
    it) is expected and only counted."""

    def __init__(self, domain: int) -> None:
        self._context = Context()
        rclpy.init(context=self._context, domain_id=domain)
        self._client = FlexarmClient('flexarm_lifecycle_client', context=self._context)
        self._stop = threading.Event()
        self.goals = 0
        self.failures: Counter[str] = Counter()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> None:
        self._client.wait_until_ready(timeout=liveness.limit(60.0))
        self._thread.start()

    def _run(self) -> None:
        rng = random.Random(0)
        count = FIRST_SAMPLES
        while not self._stop.is_set():
            try:
                result = self._client.collect(count, dataset='lifecycle',
                                              timeout=liveness.limit(60.0))
                count = 2 if result.collected >= count else count
                self._client.train('kinematic', dataset='lifecycle',
                                   timeout=liveness.limit(60.0))
                for mode in ('rigid', 'predictive', 'closed_loop'):
                    x, y, phi = rng.choice(TARGETS)
                    self._client.move_to(x, y, phi, mode, allow_extrapolation=True,
                                         timeout=liveness.limit(60.0))
                    self.goals += 1
            except (GoalFailed, TimeoutError, RuntimeError, ValueError) as exc:
                self.failures[type(exc).__name__] += 1
                self._stop.wait(0.5)

    def stop(self) -> None:
        self._stop.set()
        with contextlib.suppress(TimeoutError, RuntimeError):
            self._client.cancel_all(timeout=5.0)
        self._thread.join(timeout=liveness.limit(90.0))
        self._client.destroy_node()
        rclpy.try_shutdown(context=self._context)


def wait_back(graph: Graph, name: str, probe: Any, timeout: float) -> None:
    """Until ``name`` is discovered again (its process alive)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if graph.nodes[name].returncode is not None:
            raise RuntimeError(f'{name} died while starting: {graph.nodes[name].log_tail(20)}')
        if name in probe.get_node_names():
            return
        time.sleep(0.1)
    raise TimeoutError(f'{name} not back in the graph after {timeout:.0f} s')


def stop_once(node: NodeProcess, sig: int, wait: float) -> int | None:
    """Signal the node and wait for its exit code; None if it hung (then it is killed)."""
    assert node.process is not None
    node.signal(sig)
    try:
        return node.process.wait(timeout=wait)
    except Exception:   # subprocess.TimeoutExpired
        node.signal(signal.SIGKILL)
        node.process.wait(timeout=10.0)
        return None


class Tally:
    """Exit codes judged: per node its stops, crashes and codes; the crashes' last log lines."""

    def __init__(self, names: list[str]) -> None:
        self.per_node: dict[str, dict[str, Any]] = {
            n: {'stops': 0, 'crashes': 0, 'codes': Counter()} for n in names}
        self.crash_logs: list[str] = []
        self.hung = self.signal_exits = 0

    def judge(self, node: NodeProcess, sig: int, code: int | None) -> str:
        """Count the exit ``code`` of ``node`` after ``sig``; the line that says it."""
        name = node.spec.name
        stats = self.per_node.setdefault(name, {'stops': 0, 'crashes': 0, 'codes': Counter()})
        stats['stops'] += 1
        stats['codes'][str(code)] += 1
        if code is None:
            self.hung += 1
        elif code == -sig:
            self.signal_exits += 1
        elif code != 0:
            stats['crashes'] += 1
            if len(self.crash_logs) < 5:
                self.crash_logs.append(f'{name} exit {code} on {signal.Signals(sig).name}:\n'
                                       f'{node.log_tail(30)}')
        return f'{name}: {signal.Signals(sig).name} -> {code}'

    def judge_graph_stop(self, graph: Graph, codes: dict[str, int | None],
                         killed: str = '') -> list[str]:
        """Judge a whole-graph stop (SIGINT to every node): each node it signalled."""
        return [self.judge(graph.nodes[name], signal.SIGINT, code)
                for name, code in codes.items() if name != killed]

    def figures(self) -> dict[str, Any]:
        return {'crashes': sum(s['crashes'] for s in self.per_node.values()),
                'hung': self.hung, 'signal_exits': self.signal_exits,
                'stops': sum(s['stops'] for s in self.per_node.values()),
                'per_node': {n: {**s, 'codes': dict(s['codes'])}
                             for n, s in self.per_node.items()},
                'crash_logs': self.crash_logs}


def busy_graph(domain: int, folder: Path, bag: str) -> Graph:
    """The default graph with the recorder, at x10, its files in ``folder``."""
    return Graph(domain, folder / 'run', optional=('flexarm_recorder',),
                 report=lambda text: None,
                 parameters={'flexarm_sim': {'real_time_factor': 10.0},
                             'flexarm_recorder': {'bag_directory': str(folder / 'bags'),
                                                  'bag_name': bag},
                             'flexarm_learner': {'data_directory': str(folder / 'data'),
                                                 'model_directory': str(folder / 'models')}})


def graph_stop(domain: int, folder: Path, kill: bool, rng: random.Random, tally: Tally,
               say: Any) -> Counter[str]:
    """One whole-graph stop (module docstring): up, busy, perhaps a node killed, all stopped.
    The busy client's goals and failures."""
    graph = busy_graph(domain, folder, 'stop')
    graph.start()
    busy, killed, codes, done = None, '', {}, Counter()
    try:
        graph.wait_ready(liveness.limit(READY_S))
        busy = Busy(domain)
        busy.start()
        time.sleep(rng.uniform(1.0, 4.0))                 # a random moment of its work
        if kill:
            killed = rng.choice(sorted(graph.nodes))
            graph.nodes[killed].signal(signal.SIGKILL)
            graph.nodes[killed].process.wait(timeout=10.0)
            time.sleep(rng.uniform(0.0, 2.0))
    finally:
        if busy is not None:
            busy.stop()
            done = Counter(busy.failures, goals=busy.goals)
        codes = graph.stop(timeout=10.0)
    for line in tally.judge_graph_stop(graph, codes, killed):
        say(f'graph stop{f" after {killed} was killed" if killed else ""}: {line}')
    return done


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--cycles', type=int, default=100, help='stops per node')
    parser.add_argument('--nodes', default=','.join(ROLES),
                        help=f'roles to stop, comma-separated (of {", ".join(ROLES)})')
    parser.add_argument('--graph-stops', type=int, default=0,
                        help='then this many whole-graph stops, each of a fresh graph')
    parser.add_argument('--stop-wait', type=float, default=10.0,
                        help='[s, liveness-scaled] for a signalled node to end')
    parser.add_argument('--minutes', type=float, default=0.0,
                        help='wall-clock budget: no new cycle or graph stop after it (0: none)')
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--domain-id', type=int)
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    names = [node_name(role.strip()) for role in args.nodes.split(',') if role.strip()]
    rng = random.Random(args.seed)
    tally = Tally(names)
    cycles = graph_stops = 0
    busy: Counter[str] = Counter()          # the busy clients' goals and failures
    start = time.monotonic()

    def say(line: str) -> None:
        if not args.json:
            print(line, flush=True)

    def in_time() -> bool:
        return not args.minutes or time.monotonic() - start < 60 * args.minutes

    with tempfile.TemporaryDirectory(prefix='flexarm-lifecycle-') as tmp, \
            reserved_domain(args.domain_id) as domain:
        folder = Path(tmp)
        if args.cycles > 0:
            graph = busy_graph(domain, folder, 'lifecycle')
            graph.start()
            client, codes = None, {}
            try:
                graph.wait_ready(liveness.limit(READY_S))
                client = Busy(domain)
                client.start()
                with graph._probe() as probe:
                    for cycle in range(args.cycles):
                        if not in_time():
                            break
                        cycles += 1
                        sig = signal.SIGINT if cycle % 2 == 0 else signal.SIGTERM
                        for name in names:
                            node = graph.nodes[name]
                            time.sleep(rng.uniform(0.0, 2.0))     # a random moment of its work
                            code = stop_once(node, sig, liveness.limit(args.stop_wait))
                            say(f'cycle {cycle + 1}/{args.cycles} ' + tally.judge(node, sig, code))
                            node.close()
                            if 'bag_name' in node.parameters:     # a bag of its own per start
                                node.parameters['bag_name'] = f'lifecycle{cycle}'
                            node.start()
                            wait_back(graph, name, probe, liveness.limit(BACK_S))
            finally:
                if client is not None:
                    client.stop()
                    busy.update(client.failures, goals=client.goals)
                codes = graph.stop(timeout=10.0)
            graph_stops += 1
            for line in tally.judge_graph_stop(graph, codes):
                say(f'graph stop: {line}')
        for stop in range(args.graph_stops):
            if not in_time():
                break
            graph_stops += 1
            busy += graph_stop(domain, folder / f'stop{stop}', stop % 2 == 0, rng, tally, say)
        goals = busy.pop('goals', 0)
        figures = {**tally.figures(), 'cycles': cycles, 'graph_stops': graph_stops,
                   'busy_goals': goals, 'busy_failures': dict(busy),
                   'wall_s': round(time.monotonic() - start, 1)}
    for log in tally.crash_logs:
        say(log)
    print(json.dumps(figures))


if __name__ == '__main__':
    main()
