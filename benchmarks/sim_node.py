"""Simulator node: achieved /joint_states rate and jitter at real-time factors 1 and 10.

Starts the sim node as its own process (as ``flexarm up`` does) in a private ROS domain,
listens for ``--seconds`` of wall time, and reports the message rate in sim time and in wall
time, the real-time factor achieved and the jitter of the wall-clock inter-arrival times. The
simulator sends the ticks of one ``/clock`` period (40 ms wall) in one burst, so the jitter is
mostly that burst pattern: ~0 within a burst, a clock period between two.

    python benchmarks/sim_node.py [--seconds 10] [--json]
"""
from __future__ import annotations

import argparse
import json
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import JointState

from flexarm_bringup.launcher import NodeProcess, load_graph, ros_env, stop_all
from flexarm_core import topics


def measure(rtf: float, seconds: float, domain_id: int, run_dir: Path) -> dict[str, float]:
    spec = load_graph('sim')[0]
    proc = NodeProcess(spec, ros_env(domain_id, run_dir / 'ros_log'),
                       run_dir / f'sim_rtf{rtf:g}.log', {'real_time_factor': rtf})
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    node = rclpy.create_node('bench_sim', context=context)
    arrivals: list[tuple[float, float]] = []
    node.create_subscription(
        JointState, topics.JOINT_STATES, lambda m: arrivals.append(
            (time.monotonic(), m.header.stamp.sec + m.header.stamp.nanosec * 1e-9)), 100)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    proc.start()
    try:
        deadline = time.monotonic() + 30
        while not arrivals and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(1.0)                    # let discovery and start-up settle
        arrivals.clear()
        time.sleep(seconds)
        data = np.array(arrivals)
    finally:
        stop_all([proc])
        executor.shutdown(timeout_sec=2)
        thread.join(timeout=30)    # a spinning thread at exit aborts the interpreter (C++)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    wall, sim = data[:, 0], data[:, 1]
    gaps = np.diff(wall)
    return {'real_time_factor_set': rtf,
            'rate_sim_hz': (len(sim) - 1) / (sim[-1] - sim[0]),
            'rate_wall_hz': (len(wall) - 1) / (wall[-1] - wall[0]),
            'real_time_factor_achieved': (sim[-1] - sim[0]) / (wall[-1] - wall[0]),
            'jitter_std_ms': 1e3 * float(np.std(gaps)),
            'jitter_p99_ms': 1e3 * float(np.percentile(np.abs(gaps - gaps.mean()), 99)),
            'messages': len(sim)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=10.0)
    parser.add_argument('--domain-id', type=int, default=91)
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for rtf in (1.0, 10.0):
            rows.append(measure(rtf, args.seconds, args.domain_id, Path(tmp)))
    print('rtf  /joint_states [Hz sim]  [Hz wall]  achieved rtf  jitter std/p99 [ms]')
    for r in rows:
        print(f'{r["real_time_factor_set"]:>4g}  {r["rate_sim_hz"]:21.1f}  '
              f'{r["rate_wall_hz"]:9.1f}  {r["real_time_factor_achieved"]:12.2f}  '
              f'{r["jitter_std_ms"]:6.2f} / {r["jitter_p99_ms"]:.2f}')
    if args.json:
        print(json.dumps({'runs': rows}))


if __name__ == '__main__':
    main()
