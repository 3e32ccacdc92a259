"""Node-level: two arms of one ROS domain run on one ``/clock``, and it outlives its publisher.

arm1's simulator publishes ``/clock``, arm2's follows it. arm1's simulator stops: arm2's takes the
clock over from the time it had reached, arm2's next goal completes, and ``flexarm status``
of arm2 says who publishes the clock now. arm1's simulator comes back as a publisher of its own,
starting at time 0 (a supervisor restarting it): it yields to arm2's clock and continues
from the domain's latest time. Only the simulators and arm2's compensator run: a RIGID goal
needs no camera.
"""
from __future__ import annotations

import json
import math

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.context import Context

from flexarm_bringup.launcher import stop_all
from flexarm_cli import main
from flexarm_control.ros.client import FlexarmClient
from flexarm_core import topics
from flexarm_msgs.action import MoveToPose
from flexarm_recording.results.outcome_text import Exit
from flexarm_test_support.run_record import record_supervisor

pytestmark = [pytest.mark.node, pytest.mark.duration(35)]
SIM = {'real_time_factor': 10.0, 'error_sources': {'enabled': False}}
ARM1, ARM2 = '/arm1/flexarm_sim', '/arm2/flexarm_sim'
B6 = (1.30, -0.20, math.radians(-61))     # Table 10


def test_the_clock_outlives_its_publisher_and_a_restarted_one_continues_from_it(
        launch, domain_id, ros_node, wait_for, capsys):
    controllers: dict[str, dict[str, str]] = {}     # namespace: the sim's controller values

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for s in msg.status:
            if s.name.endswith('/flexarm_sim: controller'):
                controllers[s.name.split('/')[0]] = {v.key: v.value for v in s.values}
    ros_node.create_subscription(DiagnosticArray, topics.DIAGNOSTICS, on_diagnostics, 10)

    def clock_of(ns: str) -> str:
        return controllers.get(ns, {}).get('clock', '')

    publisher = launch('flexarm_sim', namespace='arm1', clock_source='own', **SIM)
    arm2 = [launch('flexarm_sim', namespace='arm2', clock_source='follow', **SIM),
            launch('flexarm_compensator', namespace='arm2')]
    record = record_supervisor(domain_id, 'arm2', arm2)
    wait_for(lambda: clock_of('arm2') == f'follows the /clock of {ARM1}', 60.0,
             "arm2's simulator following arm1's clock")
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    client = FlexarmClient('test_client', context=context, namespace='arm2')
    try:
        client.wait_until_ready(timeout=60.0, learner=False)
        assert client.move_to(*B6, mode='rigid', timeout=120).error_code == \
            MoveToPose.Result.SUCCESSFUL

        assert stop_all([publisher], timeout=5.0)[publisher.spec.name] is not None
        moved = client.move_to(*B6[:2], B6[2] + 0.2, mode='rigid', timeout=120)
        assert moved.error_code == MoveToPose.Result.SUCCESSFUL, moved.error_string
        taken = clock_of('arm2')
        assert taken.startswith('publishes /clock, taken over at ') and taken.endswith(ARM1), taken
        taken_at = float(taken.split('taken over at ')[1].split(' s')[0])

        capsys.readouterr()
        code = main(['status', '--json', '--namespace', 'arm2', '--domain-id', str(domain_id)])
        out = capsys.readouterr().out
        status = json.loads(out.splitlines()[-1])
        assert status['clock'].startswith('the simulator publishes /clock, taken over at'), status
        assert 'clock: the simulator publishes /clock, taken over at' in out
        assert not any('joint states' in p for p in status.get('problems', [])), status
        assert (code == Exit.OK) == (not status['problems']), out

        launch('flexarm_sim', namespace='arm1', clock_source='own', **SIM)   # at time 0
        wait_for(lambda: clock_of('arm1') == f'follows the /clock of {ARM2}', 60.0,
                 "the restarted arm1 simulator following arm2's clock")
        wait_for(lambda: float(controllers['arm1']['sim time [s]']) >= taken_at, 30.0,
                 "arm1's time continuing from the domain's")
        assert clock_of('arm2').startswith('publishes /clock'), controllers
        again = client.move_to(*B6, mode='rigid', timeout=120)
        assert again.error_code == MoveToPose.Result.SUCCESSFUL, again.error_string
    finally:
        record.unlink()
        client.destroy_node()
        rclpy.try_shutdown(context=context)
