"""Latency added by the bridge: a joint command published on ROS until the first
/joint_states that reflects it, through bridge + fake controller vs the simulator node.

Both run at real-time factor 1 with joint states at 100 Hz (10 ms period), so the figure
includes up to one period of waiting for the next state.

    python benchmarks/bridge.py [--moves 40] [--json]
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
from std_msgs.msg import Float64MultiArray

from flexarm_control import topics
from flexarm_control.experiment import reserved_domain
from flexarm_control.launcher import NodeProcess, load_graph, ros_env, stop_all


def latencies(robot: str, moves: int, domain: int, run_dir: Path) -> list[float]:
    env = ros_env(domain, run_dir / 'ros_log')
    nodes = [NodeProcess(spec, env, run_dir / f'{spec.name}.log',
                         {'use_sim_time': False} if spec.name == 'flexarm_bridge' else None)
             for spec in load_graph(robot)]
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    node = rclpy.create_node('bench_bridge', context=context)
    latest: dict[str, np.ndarray] = {}
    changed = threading.Event()
    target: dict[str, float] = {}

    def on_state(msg: JointState) -> None:
        latest['q'] = np.array(msg.position)
        if 'j4' in target and abs(msg.position[3] - target['j4']) > 1e-12 and np.sign(
                msg.velocity[3]) == np.sign(target['j4'] - target['from']):
            changed.set()

    node.create_subscription(JointState, topics.JOINT_STATES, on_state, 10)
    pub = node.create_publisher(Float64MultiArray, topics.JOINT_COMMANDS, 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    threading.Thread(target=executor.spin, daemon=True).start()
    for n in nodes:
        n.start()
    out = []
    try:
        deadline = time.monotonic() + 30
        while ('q' not in latest or not pub.get_subscription_count()) and (
                time.monotonic() < deadline):
            time.sleep(0.05)
        for i in range(moves):
            q = latest['q'].copy()
            goal = q.copy()
            goal[3] += 0.01 if i % 2 == 0 else -0.01
            changed.clear()
            target.update(j4=goal[3], **{'from': q[3]})
            start = time.monotonic()
            pub.publish(Float64MultiArray(data=goal.tolist()))
            if changed.wait(2.0):
                out.append(time.monotonic() - start)
            time.sleep(0.3)
    finally:
        stop_all(nodes)
        executor.shutdown(timeout_sec=2)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--moves', type=int, default=40)
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    figures = {}
    with tempfile.TemporaryDirectory() as tmp, reserved_domain(None) as domain:
        for robot in ('sim', 'bridge'):
            ms = 1e3 * np.array(latencies(robot, args.moves, domain, Path(tmp) / robot))
            figures[robot] = {'moves': len(ms), 'median_ms': float(np.median(ms)),
                              'p95_ms': float(np.percentile(ms, 95))}
            print(f'{robot:>6}: command -> first joint state moving toward it: median '
                  f'{figures[robot]["median_ms"]:.1f} ms, p95 {figures[robot]["p95_ms"]:.1f} ms '
                  f'({len(ms)} moves)', flush=True)
    added = figures['bridge']['median_ms'] - figures['sim']['median_ms']
    print(f'added by the bridge: {added:.1f} ms (median)')
    if args.json:
        print(json.dumps({**figures, 'added_median_ms': added}))


if __name__ == '__main__':
    main()
