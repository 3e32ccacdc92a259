"""flexarm calibrate: against the reference, the camera's tool-frame error is measured, stored
and corrected by the running vision node."""
import json
import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray

from flexarm_bringup.graph_status import calibration_status_name
from flexarm_cli import Exit, main
from flexarm_core import topics
from flexarm_msgs.msg import TipPose

pytestmark = [pytest.mark.node, pytest.mark.duration(20)]


def stamp_of(msg: TipPose) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def errors_now(ros_node, wait_for) -> np.ndarray:
    """Measured minus true tip pose (n, 3) of 3 settled frames heard from now on. The
    subscriptions stay until the test ends (see conftest's ``ros_node``)."""
    measured, truth = [], {}
    ros_node.create_subscription(TipPose, topics.TIP_POSE, measured.append, 10)
    ros_node.create_subscription(TipPose, topics.TIP_POSE_TRUTH,
                                 lambda m: truth.__setitem__(stamp_of(m), m), 100)

    def paired():
        pairs = [(m, truth[stamp_of(m)]) for m in list(measured)
                 if m.valid and m.settled and stamp_of(m) in truth]
        return pairs if len(pairs) >= 3 else None
    pairs = wait_for(paired, 60.0, '3 settled tip poses with their truth')
    return np.array([[m.pose.x - t.pose.x, m.pose.y - t.pose.y, m.pose.phi - t.pose.phi]
                     for m, t in pairs])


def calibration_said(ros_node, wait_for, starting: str) -> str:
    """The vision node's report of the camera's calibration (the line `flexarm status` and
    `up` show) once one starts with ``starting``."""
    said: list[str] = []
    subscription = ros_node.create_subscription(
        DiagnosticArray, topics.DIAGNOSTICS, lambda msg: said.extend(
            s.message for s in msg.status if s.name == calibration_status_name()), 10)
    wait_for(lambda: any(m.startswith(starting) for m in said), 30.0,
             f'a tool calibration status "{starting}…" (heard: {said[-1:]})')
    subscription.callback = lambda msg: None    # kept until the test ends (conftest's ros_node)
    return next(m for m in said if m.startswith(starting))


def test_calibration_measures_stores_and_removes_the_camera_error(launch, ros_node, wait_for,
                                                                  domain_id, tmp_path, capsys):
    launch('flexarm_sim', real_time_factor=10.0, error_sources={'enabled': True})
    path = tmp_path / 'tool_camera.json'       # none yet
    launch('flexarm_vision', tool_calibration_file=str(path))
    launch('flexarm_compensator')
    before = errors_now(ros_node, wait_for)
    assert np.hypot(before[:, 0], before[:, 1]).min() > 0.1e-3      # the camera's 0.16 mm
    calibration_said(ros_node, wait_for, f'NOT calibrated (no {tmp_path}')
    assert main(['calibrate', '--file', str(path), '--json', '--domain-id',
                 str(domain_id)]) == Exit.OK
    said = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    stored = json.loads(path.read_text())
    assert stored['tool_correction'] == said['tool_correction'] and stored['poses'] == 6
    axial, lateral, angle = stored['tool_correction']      # config/sim.yaml's true camera
    assert axial == pytest.approx(-0.13e-3, abs=0.03e-3)
    assert lateral == pytest.approx(-0.095e-3, abs=0.03e-3)
    assert math.degrees(angle) == pytest.approx(0.02, abs=0.005)
    assert 'from 6 poses' in calibration_said(ros_node, wait_for, 'calibrated ')
    after = errors_now(ros_node, wait_for)
    assert np.hypot(after[:, 0], after[:, 1]).max() < 0.04e-3
    assert np.abs(after[:, 2]).max() < math.radians(0.003)
