"""Several arms in one ROS domain: goals per minute, crosstalk and CPU per arm, for N arms.

For each N of ``--arms``: N whole graphs in one fresh ROS domain, each under its own namespace
(``arm1`` … ``armN``, what ``flexarm up --namespace armK`` starts), arm1 first: its simulator
publishes ``/clock``; the others' are told to follow it (``clock_source: follow``: the supervisor's
own choice looks for a ``/clock`` publisher for a bounded time and under heavy load might find
none yet, which makes two clocks). Each arm runs
PREDICTIVE goals in a loop from a client of its own (one thread per arm, all starting together)
until it has run ``--goals`` or ``--seconds`` have passed (wall clock; 0: no limit).

Models: each arm's compensator loads, through its ``model_path`` parameter, a model fitted before
any graph starts (the learner's default training, ``--kind`` to change it) on 40 camera-measured
samples of ``--region`` at the learner's poses (:class:`flexarm_cli.study. World`;
seed k for armK, so every arm has a model of its own). Collecting them through the graph would take
minutes per arm on two cores and measure the learner, not several arms (sample_efficiency.py times
collections). Targets: uniform in the region's box, seed ``TARGET_SEED`` + k for armK, kept when
the arm's model plans them offline within the compensator's limits (config/compensator.yaml): a
refusal would measure the model's coverage (robustness.py does), not the throughput. The simulated
world is the default one (realistic).

Crosstalk (must be 0): a monitor node lists the publishers of every topic under ``/armK/``
(images and actions' hidden topics included) every ``DISCOVERY_PERIOD``; a message received on
a topic that has a publisher outside its namespace counts (the monitor subscribes raw, nothing
decoded, to each such topic once found; publishers whose node discovery does not know yet are
not judged), and so does every goal outcome on ``/armK/compensator/outcomes`` whose
trial is not one of armK's (trial names carry the arm), and every goal of armK whose outcome was
not heard there. Apart from the outcomes the monitor subscribes to nothing else: the graph
makes camera images, tip poses and ``/tf`` only while someone subscribes to them
(:mod:`flexarm_core.demand`), so a monitor subscribed to every topic would have every arm
render and measure all the time.

CPU: user + system time of each arm's node processes and their child processes (the learner's
training worker), read by psutil over the goal phase, per wall second (1.0 = one core busy; a
child that ends meanwhile is not counted); ``benchmark``: this process (the monitor and the
clients); ``machine``: the busy share of all cores (psutil) over the goal phase and the
1-minute load average before and at its end (other work on the machine counts in the figures:
read them with it); ``seconds_per_goal``: the arms' CPU seconds per succeeded goal.
``real_time_factor`` per arm: sim seconds per wall second between its first
and last goal outcome. A machine that cannot keep up slows the shared clock down: every arm
then runs below ``--real-time-factor`` and the CPU per arm is the machine shared out; run
``--real-time-factor 1`` (a real arm's pace) to see what an arm costs when the host keeps up.

    python benchmarks/multi_arm.py [--arms 1,2,4] [--goals 20] [--seconds 0]
        [--real-time-factor 10] [--region A] [--kind KIND] [--json]

JSON (last line), per N (keys ``"1"``, ``"2"``, …): ``goals_per_min`` (``total``, ``per_arm``:
succeeded goals per wall minute, the total over the goal phase, each arm's over its own loop),
``crosstalk`` (the total), ``succeeded``, ``failed``, ``cpu`` (``per_arm`` [cores],
``per_arm_mean``, ``seconds_per_goal``, ``benchmark``, ``machine_busy``,
``load_1min_before``, ``load_1min``);
``runs`` holds every figure of each N: ``crosstalk`` by kind (``messages``, ``outcomes``,
``missing_outcomes``, ``foreign_publishers``), ``failures`` (reasons), ``real_time_factor``
per arm, ``clock_publishers`` (the publishers of ``/clock`` seen: one), ``messages`` monitored,
``ready_s``, ``goal_phase_s``, ``nodes_died``.
"""
from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import tempfile
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import deserialize_message

from flexarm_bringup.supervisor import Graph
from flexarm_cli.experiment import reserved_domain
from flexarm_cli.study import World
from flexarm_control.execution.compensator import Compensator
from flexarm_control.execution.planning import DataLimits, Refusal, plan_goal
from flexarm_control.ros.client import FlexarmClient
from flexarm_core import topics
from flexarm_core.params import load_config
from flexarm_core.processes import busy_share, cpu_seconds, descendants, machine_times
from flexarm_deflection.cross_validation import Screening
from flexarm_deflection.predictors import Predictor
from flexarm_deflection.sampling import random_targets
from flexarm_deflection.selection import fit_robust
from flexarm_msgs.msg import GoalOutcome
from flexarm_recording.topic_discovery import request_qos

TRAINING_SAMPLES = 40
TARGET_SEED = 8200        # targets of armK: TARGET_SEED + k
DISCOVERY_PERIOD = 0.5    # [s] between the monitor's looks at the graph
READY_S = 180.0           # [s] bound of each graph's bring-up
GOAL_S = 300.0            # [s] bound of one goal
# The arms after the first follow its /clock, said outright: the supervisor's own choice looks
# for a /clock publisher for 1 s, and under load it often finds none yet (two clocks). The first
# publishes it, said outright too: else the supervisor looks for another arm's /clock first (its
# CLOCK_WAIT, times the liveness factor: 20 s under test) before every run.
FOLLOWER = {'clock_source': 'follow'}
OWNER = {'clock_source': 'own'}
UNKNOWN = '_NODE_NAMESPACE_UNKNOWN_'   # discovery's placeholder until a node's name arrives


def message_type(type_name: str) -> type:
    """The Python class of ``pkg/msg/Type`` or an action's ``pkg/action/Name_FeedbackMessage``."""
    package, kind, name = type_name.split('/')
    module = importlib.import_module(f'{package}.{kind}')
    action, _, part = name.partition('_')
    return getattr(module.__dict__[action].Impl, part) if part else getattr(module, name)


def arm_names(count: int) -> list[str]:
    return [f'arm{k}' for k in range(1, count + 1)]


def train_models(names: list[str], region: str, kind: str, folder: Path) -> dict[str, Any]:
    """A model file per arm (seed k for armK) and the predictors, fitted as the learner fits."""
    learner = load_config('learner.yaml', node_name='flexarm_learner')
    world = World()
    models = {}
    for k, name in enumerate(names, start=1):
        joints, deflections = world.measured(region, TRAINING_SAMPLES, seed=k)
        predictor, _ = fit_robust(kind, {}, joints, deflections,
                                  folds=learner['validation_folds'], geometry=world.geometry,
                                  screening=Screening.from_dict(learner['training']))
        path = folder / f'{name}.model'
        predictor.save(path)
        models[name] = (path, predictor)
    return models


class Targets:
    """Random targets of a region that an arm's model plans within the compensator's limits."""

    def __init__(self, region: str) -> None:
        config = load_config('compensator.yaml', node_name='flexarm_compensator')
        self.world, self.region = World(), region
        self.compensator = Compensator(self.world.geometry, config['compensation'])
        self.limits = DataLimits(config['max_data_distance'], config['max_prediction_std'])

    def plannable(self, predictor: Predictor, count: int, seed: int) -> np.ndarray:
        """The first ``count`` of the random targets (``seed``) that ``predictor`` plans."""
        draw = count
        while draw <= 64 * count:
            drawn = random_targets(self.world.geometry, self.world.regions[self.region], draw,
                                   seed)
            kept = [t for t in drawn if not isinstance(plan_goal(
                self.compensator, 'predictive', t, predictor, self.limits), Refusal)]
            if len(kept) >= count:
                return np.array(kept[:count])
            draw *= 2
        raise RuntimeError(f'fewer than {count} targets of region {self.region} can be planned')


def arm_cpu(graph: Graph) -> dict[int, float]:
    """CPU seconds of each process of the graph's nodes and their children, by pid."""
    pids = [n.process.pid for n in graph.nodes.values() if n.process is not None]
    return {pid: cpu_seconds(pid) for pid in descendants(pids)}


class Monitor:
    """Counts every message on every ``/armK/`` topic, and those that may come from outside.

    Runs its own node (own context) in a thread; see the module docstring for what counts.
    """

    def __init__(self, domain_id: int, names: list[str]) -> None:
        self.prefixes = {f'/{name}/': f'/{name}' for name in names}
        self.messages: Counter[str] = Counter()
        self.crosstalk: Counter[str] = Counter()
        self.foreign: dict[str, set[str]] = {}       # topic: publishers outside its namespace
        self.outcomes: dict[str, list[tuple[GoalOutcome, float]]] = {n: [] for n in names}
        self.left_out: dict[str, str] = {}
        self.clock_publishers: set[str] = set()           # publishers of /clock
        self._subscriptions: dict[str, Any] = {}
        self._lock = threading.Lock()
        self._context = Context()
        rclpy.init(context=self._context, domain_id=domain_id)
        self.node = Node('flexarm_multi_arm_monitor', context=self._context)
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self.node)
        self.node.create_timer(DISCOVERY_PERIOD, self.discover,
                               clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._stop.is_set():
            self._executor.spin_once(timeout_sec=0.1)

    def _namespace(self, topic: str) -> str | None:
        return next((ns for prefix, ns in self.prefixes.items() if topic.startswith(prefix)),
                    None)

    def discover(self) -> None:
        """Note the publishers outside their namespace and those of ``/clock``; subscribe to
        the outcomes and to every topic with a publisher outside its namespace."""
        self.clock_publishers.update(f'{p.node_namespace}/{p.node_name}' for p in
                                 self.node.get_publishers_info_by_topic(topics.CLOCK)
                                 if p.node_namespace != UNKNOWN)
        for topic, _ in self.node.get_topic_names_and_types():
            ns = self._namespace(topic)
            if ns is None or topic in self.left_out:
                continue
            publishers = self.node.get_publishers_info_by_topic(topic)
            outside = {f'{p.node_namespace}/{p.node_name}' for p in publishers
                       if p.node_namespace not in (ns, UNKNOWN)}
            with self._lock:
                if outside:
                    self.foreign.setdefault(topic, set()).update(outside)
            watched = outside or topic == topics.absolute(topics.OUTCOMES, ns)
            if watched and publishers and topic not in self._subscriptions:
                self._subscribe(topic, publishers)

    def _subscribe(self, topic: str, publishers: list[Any]) -> None:
        try:
            message_class = message_type(publishers[0].topic_type)
        except (ImportError, AttributeError, KeyError, ValueError) as err:
            self.left_out[topic] = str(err)
            return
        self._subscriptions[topic] = self.node.create_subscription(
            message_class, topic, lambda raw, topic=topic: self._on_message(topic, raw),
            request_qos(publishers, 100), raw=True)

    def _on_message(self, topic: str, raw: bytes) -> None:
        with self._lock:
            self.messages[topic] += 1
            if topic in self.foreign:
                self.crosstalk[topic] += 1
        ns = self._namespace(topic)
        if ns is not None and topic == topics.absolute(topics.OUTCOMES, ns):
            self.outcomes[ns[1:]].append((deserialize_message(raw, GoalOutcome),
                                          time.monotonic()))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5.0)
        self._executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self._context)


@dataclass
class ArmRun:
    """One arm's goal loop and what came of it."""

    name: str
    targets: np.ndarray
    limit: float                        # [s, wall] no goal starts after this long
    succeeded: int = 0
    failures: list[str] = field(default_factory=list)
    trials: list[str] = field(default_factory=list)
    seconds: float = 0.0

    def run(self, client: FlexarmClient) -> None:
        start = time.monotonic()
        for i, target in enumerate(self.targets):
            if time.monotonic() - start > self.limit:
                break
            trial = f'{self.name}-g{i:03d}'
            self.trials.append(trial)
            try:
                result = client.move_to(*target, mode='predictive', trial=trial,
                                        timeout=GOAL_S)
            except (RuntimeError, TimeoutError) as exc:     # rejected, failed, lost, timed out
                self.failures.append(f'{trial}: {exc}')
                continue
            if result.error_code == 0:
                self.succeeded += 1
            else:
                self.failures.append(f'{trial}: code {result.error_code}: '
                                     f'{result.error_string}')
        self.seconds = time.monotonic() - start


def run_arms(count: int, models: dict[str, Any], targets: Targets,
             args: argparse.Namespace, folder: Path) -> dict[str, Any]:
    """N graphs in one fresh domain, the goal loops, the measurements (module docstring)."""
    names = arm_names(count)
    graphs: dict[str, Graph] = {}
    contexts: list[Context] = []
    clients: dict[str, FlexarmClient] = {}
    monitor: Monitor | None = None
    dead: list[str] = []
    with reserved_domain(None) as domain:
        started = time.monotonic()
        try:
            monitor = Monitor(domain, names)
            for name in names:
                graphs[name] = Graph(
                    domain, folder / f'run{count}' / name, namespace=name,
                    report=lambda text, name=name: print(f'  {name}: {text}', flush=True),
                    parameters={
                        'flexarm_sim': {'real_time_factor': args.real_time_factor,
                                        **(OWNER if name == names[0] else FOLLOWER)},
                        'flexarm_learner': {'data_directory': str(folder / 'data'),
                                            'model_directory': str(folder / 'models')},
                        'flexarm_compensator': {'model_path': str(models[name][0])}})
                graphs[name].start()
                if name == names[0]:
                    graphs[name].wait_ready(READY_S)    # its simulator publishes /clock
            for name in names[1:]:
                graphs[name].wait_ready(READY_S)
            for name in names:
                contexts.append(Context())
                rclpy.init(context=contexts[-1], domain_id=domain)
                clients[name] = FlexarmClient('flexarm_multi_arm', context=contexts[-1],
                                              namespace=name)
                clients[name].wait_until_ready(timeout=60.0, learner=False)
            ready_s = time.monotonic() - started
            print(f'{count} arm(s) in ROS domain {domain}: ready after {ready_s:.1f} s',
                  flush=True)
            limit = args.seconds or math.inf
            runs = {name: ArmRun(name, targets.plannable(models[name][1], args.goals,
                                                         TARGET_SEED + k), limit)
                    for k, name in enumerate(names, start=1)}
            threads = [threading.Thread(target=runs[n].run, args=(clients[n],)) for n in names]
            cpu_before = {n: arm_cpu(g) for n, g in graphs.items()}
            own_before, machine_before = cpu_seconds(os.getpid()), machine_times()
            load_before = os.getloadavg()[0]
            phase_start = time.monotonic()
            for thread in threads:
                thread.start()
            for thread in threads:
                thread.join()
            phase_s = time.monotonic() - phase_start
            cpu_after = {n: arm_cpu(g) for n, g in graphs.items()}
            own_after, machine_after = cpu_seconds(os.getpid()), machine_times()
            load = os.getloadavg()[0]
            time.sleep(2 * DISCOVERY_PERIOD)                 # the last outcomes
            for graph in graphs.values():
                dead += graph.check()
        finally:
            for client, context in zip(clients.values(), contexts):
                client.destroy_node()
                rclpy.try_shutdown(context=context)
            if monitor is not None:
                monitor.close()
            for graph in reversed(graphs.values()):
                graph.stop(timeout=10.0)
    per_arm_cpu = {n: sum(t - cpu_before[n].get(pid, 0.0) for pid, t in cpu_after[n].items())
                   / phase_s for n in names}
    return summarise(runs, monitor, per_arm_cpu, {
        'benchmark': (own_after - own_before) / phase_s,
        'machine_busy': busy_share(machine_before, machine_after),
        'load_1min_before': load_before, 'load_1min': load}, ready_s, phase_s, dead)


def summarise(runs: dict[str, ArmRun], monitor: Monitor, per_arm_cpu: dict[str, float],
              machine: dict[str, float], ready_s: float, phase_s: float,
              dead: list[str]) -> dict[str, Any]:
    """The figures of one N (module docstring)."""
    wrong_outcomes = missing = 0
    rtf = {}
    for name, run in runs.items():
        heard = monitor.outcomes[name]
        trials = {o.trial for o, _ in heard}
        wrong_outcomes += sum(o.trial not in run.trials for o, _ in heard)
        missing += len(set(run.trials) - trials)
        if len(heard) >= 2:
            (first, t0), (last, t1) = heard[0], heard[-1]
            sim = (last.stamp.sec - first.stamp.sec) + 1e-9 * (last.stamp.nanosec
                                                                - first.stamp.nanosec)
            rtf[name] = sim / (t1 - t0) if t1 > t0 else math.nan
    messages = sum(monitor.crosstalk.values())
    succeeded = sum(r.succeeded for r in runs.values())
    return {
        'arms': len(runs),
        'goals_per_min': {'total': 60.0 * succeeded / phase_s,
                          'per_arm': {n: 60.0 * r.succeeded / r.seconds if r.seconds else 0.0
                                      for n, r in runs.items()}},
        'crosstalk': {'messages': messages, 'outcomes': wrong_outcomes,
                      'missing_outcomes': missing, 'total': messages + wrong_outcomes + missing,
                      'foreign_publishers': {t: sorted(p) for t, p in monitor.foreign.items()}},
        'succeeded': succeeded, 'failed': sum(len(r.failures) for r in runs.values()),
        'failures': [f for r in runs.values() for f in r.failures],
        'cpu': {'per_arm': per_arm_cpu,
                'per_arm_mean': float(np.mean(list(per_arm_cpu.values()))),
                'seconds_per_goal': sum(per_arm_cpu.values()) * phase_s / succeeded
                if succeeded else math.nan, **machine},
        'real_time_factor': rtf, 'clock_publishers': sorted(monitor.clock_publishers),
        'messages': {'total': sum(monitor.messages.values()), 'topics': len(monitor.messages),
                     'left_out': monitor.left_out},
        'ready_s': ready_s, 'goal_phase_s': phase_s, 'nodes_died': dead}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--arms', default='1,2,4', help='arm counts to run, e.g. 1,2,4')
    parser.add_argument('--goals', type=int, default=20, help='goals per arm')
    parser.add_argument('--seconds', type=float, default=0.0,
                        help='wall seconds after which no goal starts (0: no limit)')
    parser.add_argument('--real-time-factor', type=float, default=10.0,
                        help="the simulators' real-time factor (the first arm's sets /clock)")
    parser.add_argument('--region', default='A', help='working region of the targets')
    parser.add_argument('--kind', help="predictor kind (default: the learner's)")
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    args = parser.parse_args()
    counts = [int(n) for n in args.arms.split(',')]
    kind = args.kind or load_config('learner.yaml', node_name='flexarm_learner')['default_kind']
    results: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        started = time.monotonic()
        models = train_models(arm_names(max(counts)), args.region, kind, Path(tmp))
        targets = Targets(args.region)
        print(f'{len(models)} models ({kind}, {TRAINING_SAMPLES} samples of region '
              f'{args.region}) fitted in {time.monotonic() - started:.1f} s', flush=True)
        for count in counts:
            r = run_arms(count, models, targets, args, Path(tmp))
            results[str(count)] = r
            print(f'  {count} arm(s): {r["succeeded"]} succeeded, {r["failed"]} failed in '
                  f'{r["goal_phase_s"]:.0f} s; crosstalk {r["crosstalk"]["total"]}; '
                  f'{r["messages"]["total"]} messages on {r["messages"]["topics"]} topics '
                  'monitored', flush=True)
            for failure in r['failures'][:5]:
                print(f'    failed: {failure}')
    print('arms  goals/min: total  per arm  crosstalk  succeeded  failed  CPU/arm [cores]  '
          'CPU s/goal  benchmark  machine busy  load  sim x real')
    for count, r in results.items():
        per_arm = r['goals_per_min']['per_arm'].values()
        rtf = [v for v in r['real_time_factor'].values() if math.isfinite(v)]
        cpu = r['cpu']
        print(f'{count:>4}  {r["goals_per_min"]["total"]:16.1f}  '
              f'{float(np.mean(list(per_arm))):7.1f}  {r["crosstalk"]["total"]:9d}  '
              f'{r["succeeded"]:9d}  {r["failed"]:6d}  {cpu["per_arm_mean"]:15.2f}  '
              f'{cpu["seconds_per_goal"]:10.2f}  '
              f'{cpu["benchmark"]:9.2f}  {100 * cpu["machine_busy"]:10.0f} %  '
              f'{cpu["load_1min"]:4.1f}  {float(np.mean(rtf)) if rtf else math.nan:10.2f}')
    if args.json:
        print(json.dumps({
            'goals': args.goals, 'seconds': args.seconds, 'region': args.region, 'kind': kind,
            'real_time_factor': args.real_time_factor,
            **{key: {n: r[key] for n, r in results.items()}
               for key in ('goals_per_min', 'succeeded', 'failed', 'cpu')},
            'crosstalk': {n: r['crosstalk']['total'] for n, r in results.items()},
            'runs': results}))

if __name__ == '__main__':
    main()
