"""The URDF's effort limits against the gravity model of the arm's masses: each drive holds the
loaded arm anywhere in its limits, with the description's margin at full extension."""
import numpy as np
import pytest

from flexarm_core.kinematics import ArmGeometry
from flexarm_core.params import load_config
from flexarm_description.chain import TIP_FRAME
from flexarm_description.urdf_model import EFFORT_MARGIN, PAYLOAD, joint_efforts, robot_description
from flexarm_learning.urdf_arm import GRAVITY, UrdfArm

ARM = load_config('arm.yaml')['arm']
INERTIA = ARM['inertia']


@pytest.fixture(scope='module')
def geometry() -> ArmGeometry:
    return ArmGeometry.from_dict(ARM)


def moments(geometry: ArmGeometry, poses: np.ndarray) -> np.ndarray:
    """(N, 4) [N·m]: the gravity moments about the joints with ``PAYLOAD``, through the
    learning core's reading of the description's URDF."""
    arm = UrdfArm.from_xml(robot_description(geometry, INERTIA, hardware=''), TIP_FRAME)
    return -arm.gravity_moments(arm.chain_at(poses, np.zeros(3)), PAYLOAD)[:, :, 1]


def test_efforts_are_the_margin_over_the_gravity_model_at_full_extension(geometry) -> None:
    efforts = joint_efforts(geometry, INERTIA)
    stretched = np.array([[0.0, geometry.upper[1], 0.0, 0.0]])
    held = moments(geometry, stretched)[0]       # about joint1, the guide, joint3, joint4
    for name, moment in zip(('joint1', 'joint3', 'joint4'), held[[0, 2, 3]]):
        assert efforts[name] == pytest.approx(EFFORT_MARGIN * abs(moment))
    lifted = sum(INERTIA['masses'].values()) - INERTIA['masses']['second_axis'] + PAYLOAD
    assert efforts['joint2'] == pytest.approx(EFFORT_MARGIN * np.linalg.norm(GRAVITY) * lifted)


def test_the_drives_hold_the_loaded_arm_anywhere_in_its_limits(geometry) -> None:
    efforts = joint_efforts(geometry, INERTIA)
    poses = np.random.default_rng(5).uniform(geometry.lower, geometry.upper, (2000, 4))
    loads = np.abs(moments(geometry, poses))
    held = [efforts[n] for n in ('joint1', 'joint3', 'joint4')]
    assert np.all(loads[:, [0, 2, 3]].max(axis=0) < held)
