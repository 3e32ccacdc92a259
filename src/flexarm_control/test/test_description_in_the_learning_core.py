"""The JAERI arm's robot description on the URDF-general learning core's path: the URDF that
``flexarm urdf`` writes, read by Pinocchio (:class:`flexarm_learning.urdf_arm.UrdfArm`), gives
the planar kinematics every node runs and the grey-box's gravity moments."""
from __future__ import annotations

import numpy as np
import pytest

from flexarm_control.learning.predictors.greybox import load_arm
from flexarm_core.kinematics import JOINT_NAMES, ArmGeometry, forward
from flexarm_core.params import load_config
from flexarm_description.chain import TIP_FRAME
from flexarm_description.urdf_model import robot_description
from flexarm_learning.urdf_arm import UrdfArm


@pytest.fixture(scope='module')
def arm() -> UrdfArm:
    config = load_config('arm.yaml')['arm']
    xml = robot_description(ArmGeometry.from_dict(config), config['inertia'], hardware='')
    return UrdfArm.from_xml(xml, TIP_FRAME)


@pytest.fixture(scope='module')
def rows() -> np.ndarray:
    config = load_config('arm.yaml')['arm']
    geometry = ArmGeometry.from_dict(config)
    rng = np.random.default_rng(3)
    return rng.uniform(geometry.lower, geometry.upper, size=(100, 4))


def test_its_chain_is_the_four_joints_and_its_tip_the_planar_kinematics(arm, rows):
    geometry = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])
    assert arm.joint_names == tuple(JOINT_NAMES)
    assert list(arm.prismatic) == [False, True, False, False]
    tips = arm.chain_at(rows, np.zeros(3)).target
    planar = forward(geometry, rows)
    np.testing.assert_allclose(tips[:, [0, 2]], planar[:, :2], atol=1e-12)
    np.testing.assert_allclose(tips[:, 1], 0.0, atol=1e-12)


def test_its_gravity_moments_are_the_greyboxs(arm, rows):
    """About joints 1, 3 and 4 the same to round-off (the joints turn about −y: the planar
    moment is the URDF's y moment with its sign turned). The No.2 arm's guide: the URDF's is
    about the guide itself, 15 mm beside joint1's axis (config ``offset``), the grey-box's
    about joint1's axis: they differ by the weight beyond the guide times that lever at most."""
    masses = load_arm()
    payload = np.linspace(0.0, 10.0, len(rows))
    ours = arm.gravity_moments(arm.chain_at(rows, np.zeros(3)), payload)[:, :, 1]
    theirs = masses.moments(rows, payload)
    np.testing.assert_allclose(-ours[:, [0, 2, 3]], theirs[:, [0, 2, 3]], atol=1e-9)
    beyond = 9.80665 * (sum(masses.masses.values()) - masses.masses['second_axis'] + payload)
    gap = np.abs(-ours[:, 1] - theirs[:, 1])
    assert np.all(gap <= beyond * masses.offset + 1e-9)
    assert gap.max() > 0.1      # the two pivots are apart: not one moment twice
