"""The graph's own footprint: CPU and memory of each node idle at x1 and x10 real time and
while collecting at x10, and the real-time factor the simulator achieves meanwhile; the same
at x10 with the recorder on (``flexarm up --record``, as ``flexarm demo`` records its run).

Starts the default graph of ``flexarm up`` (simulated robot, supervisor API) in a free ROS
domain (or ``--domain-id``), three times: at a real-time factor of 1, then of 10 (the
simulator's factor is fixed at start), then of 10 with the recorder (its default topics, into a
temporary bag; ``--no-record`` leaves this graph out). Each time it waits until the graph is
ready and ``--settle`` seconds more (start-up work: imports, discovery), then measures a
stretch of ``--seconds`` doing nothing (``idle_x1``, ``idle_x10``, ``idle_x10_recorded``); at
x10 it then collects ``--samples`` deflection samples through the learner's
``/collect_samples`` (:class:`~flexarm_control.ros.client.FlexarmClient`, into a temporary data
folder) and measures that stretch too (``collect_x10``, ``collect_x10_recorded``).

CPU: user + system time of each node's process and its child processes (psutil) at the
start and end of a stretch, per wall second (1.0 = one core busy: the stretch's own figure,
not the lifetime average ``ps`` shows). RSS: the resident set of the same processes (psutil)
at the end of the stretch. Achieved real-time factor: sim time advanced (``/clock``, sampled
at the start and end) per wall second. With each stretch: ``machine_busy``, the busy share of
all cores (psutil), ``load_1min`` at its end and ``benchmark_cores``, this process (the client
during the collection): other work on the machine disturbs the figures, read them with it.

    python benchmarks/footprint.py [--settle 10] [--seconds 30] [--samples 20]
        [--domain-id N] [--json]
    python benchmarks/footprint.py --smoke --json        # shortest stretches, 2 samples
        [--graphs x1,x10,x10_recorded]                   # which of the three graphs

JSON (last line): ``idle_x1``, ``idle_x10``, ``collect_x10`` (and ``idle_x10_recorded``,
``collect_x10_recorded``), each with ``total_cores``, ``achieved_rtf``, ``wall_s``, ``rss_mb``,
``machine_busy``, ``load_1min``, ``benchmark_cores`` (the collections also
``s_per_sample_wall``, ``collected``, ``error_code``); ``rss_mb_total`` (the largest total of
the stretches); ``nodes``: per node and stretch ``cores`` and ``rss_mb``; ``recorder``: the
recorder's own ``cores`` per recorded stretch (``idle_x10``, ``collect_x10``), and its bag's
``messages`` and ``bag_mb`` (absent with ``--no-record``).
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import psutil
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock

from flexarm_bringup.supervisor import Graph
from flexarm_cli.experiment import reserved_domain
from flexarm_control.ros.client import FlexarmClient
from flexarm_core import topics
from flexarm_core.processes import busy_share, cpu_seconds, descendants, machine_times
from flexarm_recording.bag_tools import bag_info

READY_S = 120.0        # [s] bound of the graph's bring-up
SMOKE = {'settle': 1.0, 'seconds': 3.0, 'samples': 2}
GRAPHS = {'x1': (1.0, False), 'x10': (10.0, False), 'x10_recorded': (10.0, True)}  # rtf, bag
RECORDER = 'flexarm_recorder'


def usage(pid: int) -> tuple[float, float]:
    """(CPU seconds, RSS MB) of ``pid`` and its children; (0, 0) for a process that is gone."""
    members = descendants([pid])
    return sum(map(cpu_seconds, members)), sum(map(rss_mb, members))


def rss_mb(pid: int) -> float:
    """The resident set of the process ``pid`` [MB] (0 once it is gone)."""
    try:
        return psutil.Process(pid).memory_info().rss / 2**20
    except psutil.Error:
        return 0.0


class SimClock:
    """The simulated time on ``/clock``, read on demand (a raw keep-last-1 subscription that
    is taken only when sampled: the benchmark adds no callbacks while it measures)."""

    def __init__(self, domain_id: int) -> None:
        self._context = Context()
        rclpy.init(context=self._context, domain_id=domain_id)
        self._node = rclpy.create_node('flexarm_footprint', context=self._context)
        self._latest: bytes | None = None
        self._node.create_subscription(Clock, topics.CLOCK,
                                       lambda raw: setattr(self, '_latest', raw), 1, raw=True)
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)

    def sample(self, timeout: float = 10.0) -> float:
        """The sim time [s] of the next ``/clock`` to arrive."""
        self._executor.spin_once(timeout_sec=0.0)       # what is queued is the past
        self._latest = None
        deadline = time.monotonic() + timeout
        while self._latest is None:
            if time.monotonic() > deadline:
                raise TimeoutError(f'no /clock within {timeout:.0f} s')
            self._executor.spin_once(timeout_sec=0.1)
        stamp = deserialize_message(self._latest, Clock).clock
        return stamp.sec + stamp.nanosec * 1e-9

    def close(self) -> None:
        self._executor.shutdown(timeout_sec=2.0)
        self._node.destroy_node()
        rclpy.try_shutdown(context=self._context)


def measure(graph: Graph, clock: SimClock, work: Callable[[], dict[str, Any]]
            ) -> tuple[dict[str, Any], dict[str, dict[str, float]]]:
    """Run ``work()`` and measure it: the stretch's figures (with what ``work`` returned) and
    per node ``cores`` and ``rss_mb``."""
    pids = {name: node.process.pid for name, node in graph.nodes.items() if node.process}
    before = {name: usage(pid)[0] for name, pid in pids.items()}
    own_before, machine_before = time.process_time(), machine_times()
    sim_start = clock.sample()
    start = time.monotonic()
    extra = work()
    sim_end = clock.sample()
    wall = time.monotonic() - start
    after = {name: usage(pid) for name, pid in pids.items()}
    own, machine = time.process_time(), machine_times()
    nodes = {name: {'cores': (after[name][0] - before[name]) / wall,
                    'rss_mb': after[name][1]} for name in pids}
    return {'total_cores': sum(n['cores'] for n in nodes.values()),
            'achieved_rtf': (sim_end - sim_start) / wall, 'wall_s': wall,
            'rss_mb': sum(n['rss_mb'] for n in nodes.values()),
            'machine_busy': busy_share(machine_before, machine),
            'load_1min': os.getloadavg()[0], 'benchmark_cores': (own - own_before) / wall,
            **extra}, nodes


def idle(seconds: float) -> Callable[[], dict[str, Any]]:
    def work() -> dict[str, Any]:
        time.sleep(seconds)
        return {}
    return work


def collection(client: FlexarmClient, samples: int) -> Callable[[], dict[str, Any]]:
    def work() -> dict[str, Any]:
        start = time.monotonic()
        result = client.collect(samples, dataset='footprint', timeout=600.0)
        return {'s_per_sample_wall': (time.monotonic() - start) / max(1, result.collected),
                'collected': result.collected, 'error_code': result.error_code}
    return work


def run_graph(domain: int, folder: Path, rtf: float, args: argparse.Namespace,
              record: bool = False
              ) -> dict[str, tuple[dict[str, Any], dict[str, dict[str, float]]]]:
    """One graph at ``rtf`` (with the recorder if ``record``): its idle stretch and, at x10,
    the collection."""
    suffix = '_recorded' if record else ''
    graph = Graph(domain, folder / f'x{rtf:g}{suffix}', report=lambda text: print(f'  {text}'),
                  parameters={'flexarm_sim': {'real_time_factor': rtf},
                              'flexarm_learner': {'data_directory': str(folder / 'data'),
                                                  'model_directory': str(folder / 'models')},
                              RECORDER: {'bag_directory': str(folder / 'bags'),
                                         'bag_name': 'footprint'}},
                  optional=(RECORDER,) if record else ())
    stretches = {}
    clock = client = context = None
    graph.start()
    try:
        graph.wait_ready(READY_S)
        clock = SimClock(domain)
        if rtf > 1:
            context = Context()
            rclpy.init(context=context, domain_id=domain)
            client = FlexarmClient('flexarm_footprint_client', context=context)
            client.wait_until_ready(timeout=60.0)
        print(f'x{rtf:g}{suffix}: ready; settling {args.settle:g} s', flush=True)
        time.sleep(args.settle)
        stretches[f'idle_x{rtf:g}{suffix}'] = measure(graph, clock, idle(args.seconds))
        if client is not None:
            stretches[f'collect_x{rtf:g}{suffix}'] = measure(
                graph, clock, collection(client, args.samples))
        dead = graph.check()
        if dead:
            raise RuntimeError(f'nodes died while measured: {", ".join(dead)}')
    finally:
        if client is not None:
            client.destroy_node()
            rclpy.try_shutdown(context=context)
        if clock is not None:
            clock.close()
        graph.stop()
    return stretches


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--settle', type=float, default=10.0,
                        help='[s] wait after ready before measuring')
    parser.add_argument('--seconds', type=float, default=30.0, help='[s] of each idle stretch')
    parser.add_argument('--samples', type=int, default=20, help='samples of the collection')
    smoke = ', '.join(f'--{key} {value:g}' for key, value in SMOKE.items())
    parser.add_argument('--smoke', action='store_true', help=f'shortest run: {smoke}')
    parser.add_argument('--no-record', action='store_true',
                        help='leave out the graph with the recorder')
    parser.add_argument('--graphs', default=','.join(GRAPHS),
                        help=f'the graphs to run, of {",".join(GRAPHS)} (a smoke run of the '
                        'suite needs one: each starts the whole graph)')
    parser.add_argument('--domain-id', type=int, help='ROS domain (default: a free one)')
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    args = parser.parse_args()
    unknown = set(args.graphs.split(',')) - set(GRAPHS)
    if unknown:
        parser.error(f'--graphs: no graph {", ".join(sorted(unknown))}; of {",".join(GRAPHS)}')
    if args.smoke:
        vars(args).update(SMOKE)
    print(f'load average before: {os.getloadavg()[0]:.2f}', flush=True)
    stretches: dict[str, tuple[dict[str, Any], dict[str, dict[str, float]]]] = {}
    recorder: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp, reserved_domain(args.domain_id) as domain:
        for name in args.graphs.split(','):
            rtf, record = GRAPHS[name]
            if record and args.no_record:
                continue
            stretches.update(run_graph(domain, Path(tmp), rtf, args, record))
        if any(record for _, record in map(GRAPHS.get, args.graphs.split(','))) and (
                not args.no_record):
            info = bag_info(Path(tmp) / 'bags' / 'footprint')
            recorder = {'cores': {key.removesuffix('_recorded'): nodes[RECORDER]['cores']
                                  for key, (_, nodes) in stretches.items() if RECORDER in nodes},
                        'messages': info['message_count'], 'bag_mb': info['size_bytes'] / 1e6}
    names = sorted({name for _, nodes in stretches.values() for name in nodes})
    print(f'{"node":26}' + ''.join(f'{k:>24}' for k in stretches) + '   [cores / RSS MB]')
    for name in names:
        print(f'{name:26}' + ''.join(
            f'{nodes[name]["cores"]:15.3f} / {nodes[name]["rss_mb"]:5.0f}' if name in nodes
            else f'{"-":>24}' for _, nodes in stretches.values()))
    for key, (figures, _) in stretches.items():
        extra = (f', {figures["s_per_sample_wall"]:.2f} s/sample wall '
                 f'({figures["collected"]} collected)' if 'collected' in figures else '')
        print(f'{key}: {figures["total_cores"]:.3f} cores, {figures["rss_mb"]:.0f} MB, '
              f'x{figures["achieved_rtf"]:.2f} real time over {figures["wall_s"]:.1f} s'
              f'{extra}; machine busy {100 * figures["machine_busy"]:.0f} %, load '
              f'{figures["load_1min"]:.2f}, benchmark {figures["benchmark_cores"]:.3f} cores')
    if recorder:
        print('recorder: ' + ', '.join(f'{cores:.3f} cores {key}'
                                       for key, cores in recorder['cores'].items())
              + f'; {recorder["messages"]} messages, bag {recorder["bag_mb"]:.1f} MB')
    if args.json:
        print(json.dumps({
            'settle_s': args.settle, 'seconds': args.seconds, 'samples': args.samples,
            **{key: figures for key, (figures, _) in stretches.items()},
            **({'recorder': recorder} if recorder else {}),
            'rss_mb_total': max(figures['rss_mb'] for figures, _ in stretches.values()),
            'nodes': {name: {key: nodes[name] for key, (_, nodes) in stretches.items()
                             if name in nodes} for name in names}}))


if __name__ == '__main__':
    main()
