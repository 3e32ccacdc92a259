"""The published URDF is one that ROS's own URDF parser (urdf_parser_py, as xacro and the
description tools use it) reads, and its chain is the kinematics every node runs: the parsed
joints' origins and axes, composed from base_link to tip_link, put the tool where
flexarm_core.kinematics.forward does."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from urdf_parser_py.urdf import URDF

from flexarm_core.kinematics import JOINT_NAMES, ArmGeometry, forward
from flexarm_core.params import load_config
from flexarm_description.chain import BASE_FRAME, TIP_FRAME
from flexarm_description.urdf_model import ROBOT_NAME, published_description

# what the state publisher is given (config/graph.yaml: its params files, under its name)
PARAMETERS = load_config('arm.yaml', 'camera.yaml', 'description.yaml',
                         node_name='flexarm_state_publisher')


@pytest.fixture(scope='module')
def robot() -> URDF:
    return URDF.from_xml_string(published_description(PARAMETERS))


def parsed_tip(robot: URDF, q: dict[str, float]) -> np.ndarray:
    """(x, y_up, phi) of tip_link in base_link: each joint's origin (xyz, then rpy about
    fixed x, y, z), then its motion along or about its axis, composed down the chain."""
    pose = np.eye(4)
    for name in robot.get_chain(BASE_FRAME, TIP_FRAME, links=False):
        joint = robot.joint_map[name]
        step = np.eye(4)
        step[:3, :3] = Rotation.from_euler('xyz', joint.origin.rpy).as_matrix()
        step[:3, 3] = joint.origin.xyz
        motion = np.eye(4)
        if joint.type == 'revolute':
            motion[:3, :3] = Rotation.from_rotvec(np.array(joint.axis) * q[name]).as_matrix()
        elif joint.type == 'prismatic':
            motion[:3, 3] = np.array(joint.axis) * q[name]
        pose = pose @ step @ motion
    return np.array([pose[0, 3], pose[2, 3], math.atan2(pose[2, 0], pose[0, 0])])


def test_ros_parser_reads_the_arm_with_its_limits(robot: URDF) -> None:
    geometry = ArmGeometry.from_dict(PARAMETERS['arm'])
    assert robot.name == ROBOT_NAME and robot.get_root() == BASE_FRAME
    assert robot.get_chain(BASE_FRAME, TIP_FRAME, links=False) == [*JOINT_NAMES, 'tip_joint']
    for i, name in enumerate(JOINT_NAMES):
        limit = robot.joint_map[name].limit
        assert (limit.lower, limit.upper) == (geometry.lower[i], geometry.upper[i])
        assert limit.velocity == geometry.velocity[i] and limit.effort > 0


def test_the_parsed_chain_is_the_kinematic_model(robot: URDF) -> None:
    geometry = ArmGeometry.from_dict(PARAMETERS['arm'])
    lower, upper = np.asarray(geometry.lower), np.asarray(geometry.upper)
    joints = np.random.default_rng(7).uniform(lower, upper, (8, 4))
    for q in [np.zeros(4), lower, upper, *joints]:
        tip = parsed_tip(robot, dict(zip(JOINT_NAMES, q)))
        expected = forward(geometry, q)
        np.testing.assert_allclose(tip[:2], expected[:2], atol=1e-12)
        assert math.remainder(tip[2] - expected[2], math.tau) == pytest.approx(0.0, abs=1e-12)
