"""A goal its client abandons: how long until the compensator ends it.

A raw rclpy action client (no flexarm code: what a tester's script does) runs in a process of
its own, sends a long CLOSED_LOOP goal and is killed with SIGKILL once the arm moves;
:func:`abandoned_goal_s` returns the seconds from the kill until the compensator published the
goal's end on ``compensator/outcomes``, and fails unless the server cancelled it for its
sender's leaving. It needs a running graph with the simulator and the compensator in the
domain (the vision node is not needed: the goal ends mid-move). For tests/test_faults_goals.py
and benchmarks (which put tests/ on sys.path); as a script, for a caller that keeps DDS out of
its own process::

    python -m flexarm_test_support.abandoned_goal --domain-id N [--namespace NS]  # last: JSON
"""
from __future__ import annotations

import argparse
import json
import math
import queue
import signal
import subprocess
import sys
import threading
import time
import uuid

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor

from flexarm_bringup.launcher import ros_env
from flexarm_core import liveness, topics
from flexarm_core.dds_shm import owned_shm, remove_shm_of_dead
from flexarm_msgs.action import MoveToPose
from flexarm_msgs.msg import GoalOutcome

B4 = (1.0, -0.5, math.radians(-100))   # [m, m, rad] Table 10: a long move from the start pose
READY = 30.0   # [s, wall, scaled] for the sender to reach the server or the arm to move
# The sender: sends one CLOSED_LOOP goal with the most corrections the server allows and says
# 'accepted', then 'moving' at the first moving feedback (each with its time.monotonic()), and
# 'result CODE REASON' at the end.
SENDER = r'''
import sys
import time
import rclpy
from rclpy.action import ActionClient
from flexarm_msgs.action import MoveToPose
from flexarm_msgs.msg import PlanarPose

name, action, trial, x, y, phi, ready = sys.argv[1:]
rclpy.init()
node = rclpy.create_node(name)
client = ActionClient(node, MoveToPose, action)
if not client.wait_for_server(timeout_sec=float(ready)):
    sys.exit(f'no server {action}')
said = set()

def feedback(msg):
    if msg.feedback.phase == 'moving' and 'moving' not in said:
        said.add('moving')
        print('moving', time.monotonic(), flush=True)

goal = MoveToPose.Goal(target=PlanarPose(x=float(x), y=float(y), phi=float(phi)),
                       mode=MoveToPose.Goal.MODE_CLOSED_LOOP, max_corrections=10, trial=trial)
sent = client.send_goal_async(goal, feedback_callback=feedback)
rclpy.spin_until_future_complete(node, sent)
if not sent.result().accepted:
    sys.exit('rejected')
print('accepted', time.monotonic(), flush=True)
done = sent.result().get_result_async()
rclpy.spin_until_future_complete(node, done)
print('result', done.result().result.error_code, done.result().result.error_string, flush=True)
'''


class GoalSender:
    """The sender's process (node ``name``), and the lines it said."""

    def __init__(self, domain_id: int, namespace: str = '', name: str = 'goal_sender',
                 trial: str = '') -> None:
        self.trial = trial or f'sent-{uuid.uuid4().hex[:8]}'
        self.process = subprocess.Popen(
            [sys.executable, '-c', SENDER, name, topics.absolute(topics.MOVE_TO_POSE, namespace),
             self.trial, *(str(v) for v in B4), str(liveness.limit(READY))],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=ros_env(domain_id))
        self.said: list[str] = []
        self._lines: queue.Queue[str | None] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.process.stdout:
            self.said.append(line.rstrip('\n'))
            self._lines.put(self.said[-1])
        self._lines.put(None)

    def wait_for(self, word: str, timeout: float) -> str:
        """The first line said from now on that starts with ``word``; RuntimeError if the
        sender ends or ``timeout`` s pass first."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self._lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                line = None
            if line is None:
                self.kill()
                raise RuntimeError(f'the goal sender did not say {word!r} within {timeout:.0f} '
                                   f's: {" | ".join(self.said[-5:])}')
            if line.startswith(word):
                return line

    def kill(self) -> None:
        """SIGKILL (no goodbye to DDS, no cancel) and reap it; then remove the shared memory
        it owned, which a SIGKILLed participant leaves behind."""
        if self.process.poll() is None:
            owned = owned_shm(self.process.pid)
            self.process.send_signal(signal.SIGKILL)
            self.process.wait()
            remove_shm_of_dead(owned)
        self.process.wait()


class Outcomes:
    """``compensator/outcomes`` of the arm in ``namespace``, each with its arrival time
    [monotonic], heard by a node of its own context (no action client: not a sender)."""

    def __init__(self, domain_id: int, namespace: str = '') -> None:
        self._context = Context()
        rclpy.init(context=self._context, domain_id=domain_id)
        self._node = rclpy.create_node(f'outcome_watch_{uuid.uuid4().hex[:8]}',
                                       context=self._context)
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)
        self.heard: list[tuple[float, GoalOutcome]] = []
        self._topic = topics.absolute(topics.OUTCOMES, namespace)
        self._node.create_subscription(GoalOutcome, self._topic, lambda m: self.heard.append(
            (time.monotonic(), m)), 10)

    def wait_for_server(self, timeout: float) -> None:
        """Until the compensator's outcome publisher is discovered."""
        deadline = time.monotonic() + timeout
        while not self._node.count_publishers(self._topic):
            if time.monotonic() > deadline:
                raise TimeoutError(f'no publisher of {self._topic} within {timeout:.0f} s')
            self._executor.spin_once(timeout_sec=0.05)

    def of(self, trial: str, timeout: float) -> tuple[float, GoalOutcome]:
        """The outcome of the goal ``trial`` and when it came."""
        deadline = time.monotonic() + timeout
        while True:
            found = [(t, m) for t, m in self.heard if m.trial == trial]
            if found:
                return found[0]
            if time.monotonic() > deadline:
                raise TimeoutError(f'the goal {trial} did not end within {timeout:.0f} s')
            self._executor.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        self._executor.shutdown(timeout_sec=1.0)
        self._node.destroy_node()
        rclpy.try_shutdown(context=self._context)


def abandoned_goal_s(domain_id: int, namespace: str = '', timeout: float = 60.0) -> float:
    """Seconds from the SIGKILL of a goal's only client, while the arm moves, until the
    compensator had cancelled the goal (module docstring); TimeoutError when it was not
    within ``timeout`` s (scaled: :mod:`flexarm_core.liveness`), RuntimeError when the
    goal ended otherwise."""
    outcomes = Outcomes(domain_id, namespace)
    try:
        outcomes.wait_for_server(liveness.limit(READY))
        sender = GoalSender(domain_id, namespace, 'abandoning_client')
        moving = float(sender.wait_for('moving', liveness.limit(READY)).split()[1])
        sender.kill()
        killed = time.monotonic()
        ended, outcome = outcomes.of(sender.trial, liveness.limit(timeout))
    finally:
        outcomes.close()
    if (outcome.error_code != MoveToPose.Result.CANCELED
            or 'canceled by the server' not in outcome.error_string):
        raise RuntimeError(
            f'the abandoned goal ended otherwise ({outcome.error_code}) {ended - killed:.1f} s '
            f'after the kill: {outcome.error_string} (the sender was killed '
            f'{killed - moving:.1f} s after it heard the arm move; it said '
            f'{" | ".join(sender.said)})')
    return ended - killed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--domain-id', type=int, required=True)
    parser.add_argument('--namespace', default='')
    parser.add_argument('--timeout', type=float, default=60.0)
    args = parser.parse_args()
    print(json.dumps({'abandoned_goal_s': abandoned_goal_s(args.domain_id, args.namespace,
                                                           args.timeout)}))


if __name__ == '__main__':
    main()
