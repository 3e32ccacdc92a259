"""The JAERI arm's robot description on the URDF-general learning core's path: the URDF that
``flexarm urdf`` writes, read by Pinocchio (:class:`flexarm_learning.urdf_arm.UrdfArm`), gives
the planar kinematics every node runs and the gravity moments the grey-box's compliances
take."""
from __future__ import annotations

import numpy as np
import pytest

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


def planar_moments(arm: UrdfArm, joints: np.ndarray, payload: float) -> np.ndarray:
    """(N, 4) [N·m]: the moments about the joints' pivots in the arm's plane (the joints turn
    about −y: the planar moment is the URDF's y moment with its sign turned)."""
    return -arm.gravity_moments(arm.chain_at(joints, np.zeros(3)), payload)[:, :, 1]


def test_its_gravity_moments_follow_the_masses(arm):
    """Stretched along +x, every joint carries a downward load, less the farther out; a
    payload adds its weight times its lever (the tip beyond each pivot: 1.4, 1.4, 0.8,
    0.4 m); hanging straight down, the wrist carries no moment."""
    stretched = np.array([[0.0, 0.6, 0.0, 0.0]])
    m = planar_moments(arm, stretched, 0.0)[0]
    assert np.all(m < 0) and m[0] < m[1] < m[2] < m[3]
    lever = np.array([1.4, 1.4, 0.8, 0.4])
    np.testing.assert_allclose(planar_moments(arm, stretched, 1.0)[0] - m, -9.80665 * lever,
                               atol=1e-9)
    hanging = np.array([[-np.pi / 2, 0.6, 0.0, 0.0]])
    assert abs(planar_moments(arm, hanging, 2.0)[0, 3]) < 1e-9
