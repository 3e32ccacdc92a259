"""Time from starting the graph (what ``flexarm up`` does) to ready, to answer ``flexarm
status``, and to shut it down.

Ready = /joint_states, /clock and /tip_pose published, /move_to_pose and /collect_samples
action servers and the /train service discovered, and every node of the graph. Status: once the
graph is ready (its supervisor record in the runs folder, as ``flexarm up``'s) and one
``flexarm status`` has answered (untimed: the nodes finish starting
meanwhile), ``--status-calls`` more, each a process of its own as an operator runs it, timed
from its start to its exit. JSON: ``ready_s``, ``status_s`` and ``stop_s`` are the medians of
the runs (of every status call), ``status_max_s`` the slowest call, ``*_runs_s`` every value.

    python benchmarks/bringup.py [--runs 3] [--status-calls 5] [--json]
"""
from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from flexarm_bringup.supervisor import Graph
from flexarm_cli.experiment import reserved_domain
from flexarm_core.paths import RUNS_DIR


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--runs', type=int, default=3)
    parser.add_argument('--status-calls', type=int, default=5)
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    ready, stop, status, count = [], [], [], 0
    RUNS_DIR.mkdir(parents=True, exist_ok=True)
    with reserved_domain(None) as domain:
        for run in range(args.runs):
            # a run folder of RUNS_DIR, as `flexarm up`'s: status finds the supervisor there
            tmp = tempfile.mkdtemp(dir=RUNS_DIR, prefix=f'bringup-{run}-')
            graph = Graph(domain, Path(tmp), optional=('flexarm_recorder',),
                          parameters={'flexarm_recorder': {'bag_directory': tmp,
                                                           'bag_name': f'b{run}'}},
                          report=lambda _: None)
            count = len(graph.nodes)
            start = time.monotonic()
            graph.start()
            try:
                graph.wait_ready(120.0)
                ready.append(time.monotonic() - start)
                calls = [status_call(domain) for _ in range(args.status_calls + 1)][1:]
                status += calls
            finally:
                start = time.monotonic()
                codes = graph.stop()
                stop.append(time.monotonic() - start)
                shutil.rmtree(tmp)
            print(f'run {run + 1}: ready in {ready[-1]:.2f} s, status in '
                  f'{", ".join(f"{c:.2f}" for c in calls)} s, stopped in {stop[-1]:.2f} s, '
                  f'exit codes {sorted(set(codes.values()))}', flush=True)
    print(f'{len(ready)} runs of {count} nodes: ready in median {statistics.median(ready):.2f} s '
          f'(max {max(ready):.2f} s); status median {statistics.median(status):.2f} s (max '
          f'{max(status):.2f} s); shutdown median {statistics.median(stop):.2f} s')
    if args.json:
        print(json.dumps({'ready_s': statistics.median(ready), 'stop_s': statistics.median(stop),
                          'status_s': statistics.median(status), 'status_max_s': max(status),
                          'ready_runs_s': ready, 'stop_runs_s': stop, 'status_runs_s': status}))


def status_call(domain: int) -> float:
    """[s] from starting ``flexarm status`` to its exit (an error if it found no graph)."""
    start = time.monotonic()
    done = subprocess.run([sys.executable, '-m', 'flexarm_cli', 'status', '--quiet',
                           '--domain-id', str(domain)], capture_output=True, text=True)
    took = time.monotonic() - start
    if done.returncode not in (0, 5):      # 5: the graph has a problem, it still answered
        raise RuntimeError(f'flexarm status exited {done.returncode}: {done.stdout[-2000:]} '
                           f'{done.stderr[-2000:]}')
    return took


if __name__ == '__main__':
    main()
