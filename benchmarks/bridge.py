"""Latency added by the bridge: a joint command published on ROS until the first
/joint_states that reflects it (a 0.01 rad step of joint4), through bridge + fake controller vs
the simulator node; and, with a relay tapping the TCP link in front of the fake controller, where
the time goes: command -> JOINT_COMMAND frame on the wire at the controller -> first
JOINT_STATE frame reflecting it on the wire -> /joint_states. The bridge's own cost is the
first and the last of these legs; the middle one is the controller's.

Everything runs at real-time factor 1 with joint states at 100 Hz (10 ms period), so the
controller's share includes up to one period of waiting for its next tick.

    python benchmarks/bridge.py [--moves 40] [--robot-only] [--domain ID] [--json]

Smoke run (a few seconds a configuration): ``--moves 1 --robot-only``.
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

from flexarm_bridge import controller_protocol as proto
from flexarm_bringup.launcher import (
    NodeProcess,
    load_graph,
    load_rehearsal,
    ros_env,
    stop_all,
)
from flexarm_cli.experiment import reserved_domain
from flexarm_core import topics
from flexarm_test_support.link_proxy import TO_CONTROLLER, TO_PC, LinkProxy

STEP = 0.01          # [rad] joint4
SETTLE = 0.4         # [s] between steps (a 0.01 rad joint4 step takes 0.24 s)
STAGES = ('command_on_wire', 'state_on_wire', 'joint_states')
ROBOT_NODES = {'sim': {'flexarm_sim'}, 'bridge': {'flexarm_bridge', 'flexarm_fake_controller'}}


class StepTimer:
    """Monotonic times at which one joint4 step shows up at each stage after its command."""

    def __init__(self, stages: tuple[str, ...]) -> None:
        self._stages = stages          # a step is done once every one of them is marked
        self._lock = threading.Lock()
        self._step: tuple[float, float] | None = None       # (from, goal) of joint4
        self.marks: dict[str, float] = {}
        self.done = threading.Event()

    def begin(self, start: float, goal: float) -> float:
        with self._lock:
            self._step, self.marks = (start, goal), {}
        self.done.clear()
        return time.monotonic()

    def reflects(self, joint4: float) -> bool:
        step = self._step
        return step is not None and (joint4 - step[0]) * (step[1] - step[0]) > 0

    def mark(self, stage: str, t: float) -> None:
        with self._lock:
            if self._step is not None and stage not in self.marks:
                self.marks[stage] = t
            if all(s in self.marks for s in self._stages):
                self.done.set()


def step_latencies(robot: str, tap: bool, moves: int, domain: int, run_dir: Path,
                   robot_only: bool = False) -> list[dict[str, float]]:
    """Per step: seconds from publishing the command to each stage it was seen at; with
    ``robot_only`` only the robot's nodes run, not the rest of the graph."""
    controller_port = 47000 + 2 * domain
    bridge_port = controller_port + 1 if tap else controller_port
    overrides = {'flexarm_bridge': {'use_sim_time': False, 'port': bridge_port},
                 'flexarm_fake_controller': {'port': controller_port}}
    env = ros_env(domain, run_dir / 'ros_log')
    specs = [*(load_rehearsal() if robot == 'bridge' else ()), *load_graph(robot)]
    nodes = [NodeProcess(spec, env, run_dir / f'{spec.name}.log', overrides.get(spec.name))
             for spec in specs if not robot_only or spec.name in ROBOT_NODES[robot]]
    # The relay marks its stages from its own thread, possibly after /joint_states (it relays
    # first): a tapped step is complete only when all three are in.
    timer = StepTimer(STAGES if tap else ('joint_states',))

    def on_frame(direction: str, t: float, frame: proto.Frame) -> None:
        if direction == TO_CONTROLLER and frame.type == proto.JOINT_COMMAND:
            timer.mark('command_on_wire', t)
        elif (direction == TO_PC and frame.type == proto.JOINT_STATE
              and timer.reflects(frame.fields['positions'][3])):
            timer.mark('state_on_wire', t)

    proxy = LinkProxy(bridge_port, controller_port, on_frame) if tap else None
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    node = rclpy.create_node('bench_bridge', context=context)
    latest: dict[str, np.ndarray] = {}

    def on_state(msg: JointState) -> None:
        latest['q'] = np.array(msg.position)
        if timer.reflects(msg.position[3]):
            timer.mark('joint_states', time.monotonic())

    node.create_subscription(JointState, topics.JOINT_STATES, on_state, 10)
    pub = node.create_publisher(Float64MultiArray, topics.JOINT_COMMANDS, 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    for n in nodes:
        n.start()
    out = []
    try:
        deadline = time.monotonic() + 30
        while ('q' not in latest or not pub.get_subscription_count()) and (
                time.monotonic() < deadline):
            time.sleep(0.05)
        if 'q' not in latest:
            raise RuntimeError(f'no /joint_states from robot {robot!r} within 30 s')
        time.sleep(1.0)                       # let the first states settle
        for i in range(moves):
            goal = latest['q'].copy()
            goal[3] += STEP if i % 2 == 0 else -STEP
            start = timer.begin(latest['q'][3], goal[3])
            pub.publish(Float64MultiArray(data=goal.tolist()))
            if timer.done.wait(2.0):
                out.append({stage: t - start for stage, t in timer.marks.items()})
            time.sleep(SETTLE)
    finally:
        stop_all(nodes)
        if proxy is not None:
            proxy.close()
        executor.shutdown(timeout_sec=2)
        thread.join(timeout=30)    # a spinning thread at exit aborts the interpreter (C++)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return out


def summary(seconds: list[float]) -> dict[str, float]:
    ms = 1e3 * np.asarray(seconds)
    return {'n': int(ms.size), 'median_ms': float(np.median(ms)),
            'p95_ms': float(np.percentile(ms, 95))}


def line(label: str, figures: dict[str, float]) -> str:
    return (f'{label:<58} median {figures["median_ms"]:5.2f} ms, p95 {figures["p95_ms"]:5.2f} ms'
            f' ({figures["n"]} steps)')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--moves', type=int, default=40, help='joint4 steps per configuration')
    parser.add_argument('--robot-only', action='store_true',
                        help='start only the robot nodes (simulator; bridge and fake controller), '
                             'not the rest of the graph: quicker and lighter, e.g. a smoke run')
    parser.add_argument('--domain', type=int, help='ROS domain (default: a free one, reserved)')
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    if args.moves < 1:
        parser.error('--moves must be at least 1')
    figures: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp, reserved_domain(args.domain) as domain:
        for label, robot, tap in (('sim', 'sim', False), ('bridge', 'bridge', False),
                                  ('bridge_tapped', 'bridge', True)):
            steps = step_latencies(robot, tap, args.moves, domain, Path(tmp) / label,
                                   args.robot_only)
            if not steps:
                raise RuntimeError(f'{label}: no step reached /joint_states within 2 s')
            figures[label] = {stage: summary([s[stage] for s in steps if stage in s])
                              for stage in STAGES if any(stage in s for s in steps)}
    inbound = [s['joint_states'] - s['state_on_wire'] for s in steps if 'state_on_wire' in s]
    figures['bridge_tapped']['wire_to_joint_states'] = summary(inbound)
    print(line('simulator node: command -> /joint_states', figures['sim']['joint_states']))
    print(line('bridge + fake controller: command -> /joint_states',
               figures['bridge']['joint_states']))
    tapped = figures['bridge_tapped']
    print('with a relay tapping the link in front of the fake controller:')
    print(line('  command -> JOINT_COMMAND on the wire at the controller',
               tapped['command_on_wire']))
    print(line('  command -> first JOINT_STATE reflecting it on the wire',
               tapped['state_on_wire']))
    print(line('  command -> /joint_states', tapped['joint_states']))
    print(line('  JOINT_STATE on the wire -> /joint_states (per step)',
               tapped['wire_to_joint_states']))
    added = figures['bridge']['joint_states']['median_ms'] - figures['sim']['joint_states'][
        'median_ms']
    print(f'added by the bridge (median, command -> /joint_states): {added:.2f} ms')
    if args.json:
        print(json.dumps({**figures, 'added_median_ms': added}))


if __name__ == '__main__':
    main()
