"""Time from starting the graph (what ``flexarm up`` does) to ready, and to shut it down.

Ready = /joint_states, /clock and /tip_pose published, /move_to_pose and /collect_samples
action servers and the /train service discovered, and every node of the graph. JSON:
``ready_s`` and ``stop_s`` are the medians of the runs, ``*_runs_s`` every run.

    python benchmarks/bringup.py [--runs 3] [--json]
"""
from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

from flexarm_bringup.experiment import reserved_domain
from flexarm_bringup.supervisor import Graph


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--runs', type=int, default=3)
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    ready, stop, count = [], [], 0
    with tempfile.TemporaryDirectory() as tmp, reserved_domain(None) as domain:
        for run in range(args.runs):
            graph = Graph(domain, Path(tmp) / f'run{run}', optional=('flexarm_recorder',),
                          parameters={'flexarm_recorder': {'bag_directory': tmp,
                                                           'bag_name': f'b{run}'}},
                          report=lambda _: None)
            count = len(graph.nodes)
            start = time.monotonic()
            graph.start()
            try:
                graph.wait_ready(120.0)
                ready.append(time.monotonic() - start)
            finally:
                start = time.monotonic()
                codes = graph.stop()
                stop.append(time.monotonic() - start)
            print(f'run {run + 1}: ready in {ready[-1]:.2f} s, stopped in {stop[-1]:.2f} s, '
                  f'exit codes {sorted(set(codes.values()))}', flush=True)
    print(f'{len(ready)} runs of {count} nodes: ready in median {statistics.median(ready):.2f} s '
          f'(max {max(ready):.2f} s); shutdown median {statistics.median(stop):.2f} s')
    if args.json:
        print(json.dumps({'ready_s': statistics.median(ready), 'stop_s': statistics.median(stop),
                          'ready_runs_s': ready, 'stop_runs_s': stop}))


if __name__ == '__main__':
    main()
