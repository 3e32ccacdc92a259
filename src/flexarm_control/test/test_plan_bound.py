"""What no model sees, at its own 95 % point: the servos' error through the arm's Jacobian
(the exact radius of its ellipse), the arm's growth, the camera after its calibration."""
import numpy as np
import pytest

from flexarm_control.execution.plan_bound import SiteErrors, radius_95
from flexarm_core.kinematics import ArmGeometry
from flexarm_core.params import load_config

GEOMETRY = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])
STRETCHED = np.array([0.0, 0.6, 0.0, 0.0])       # the tip 1.4 m out along +x


def test_the_radius_of_a_flat_error_is_1_96_sigma_and_of_a_round_one_2_45():
    assert radius_95(np.diag([1e-8, 0.0])) == pytest.approx(1.96e-4, rel=0.02)
    assert radius_95(np.diag([1e-8, 1e-8])) == pytest.approx(2.448e-4, rel=0.02)


def test_the_servos_move_the_tip_across_a_stretched_arm_and_the_growth_along_it():
    servo = SiteErrors(np.array([1e-5, 0.0, 0.0, 0.0]), (0.0, 0.0), (0.0, 0.0))
    assert servo.at(GEOMETRY, STRETCHED)[0] == pytest.approx(1.96 * 1e-5 * 1.4, rel=0.03)
    growth = SiteErrors(np.zeros(4), (0.0, 0.0), (0.0, 0.0), thermal_strain=1e-5)
    position, angle = growth.at(GEOMETRY, STRETCHED)
    assert position == pytest.approx(1.96 * 1e-5 * 1.4, rel=0.01) and angle == 0.0
    camera = SiteErrors(np.zeros(4), (1e-5, 0.0), (0.0, 0.0))
    assert camera.closed_loop((5e-5, 1e-4))[0] == pytest.approx(5e-5 + 1.96e-5, rel=1e-4)


def test_the_configured_figures_are_read_and_bad_ones_refused():
    config = load_config('compensator.yaml', node_name='flexarm_compensator')['error_bound']
    assert SiteErrors.from_dict(config).thermal_strain > 0
    with pytest.raises(ValueError, match='all >= 0'):
        SiteErrors.from_dict({**config, 'tool_residual': [-1e-6, 0.0]})
    with pytest.raises(ValueError, match='joint_repeatability needs 4'):
        SiteErrors.from_dict({**config, 'joint_repeatability': [0.0]})
