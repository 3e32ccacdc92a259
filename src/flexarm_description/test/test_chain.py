"""The chain of frames and the URDF agree with the rigid kinematics every node runs."""
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from flexarm_core import plane
from flexarm_core.kinematics import JOINT_NAMES, ArmGeometry, forward
from flexarm_core.params import load_config
from flexarm_description.chain import (
    BASE_FRAME,
    CAMERA_OPTICAL_FRAME,
    TIP_FRAME,
    Transform,
    arm_joints,
    compose,
    fixed_transforms,
    moving_transforms,
    planar_pose,
    planar_transform,
    plane_transform,
)
from flexarm_description.urdf_model import robot_description

INERTIA = load_config('arm.yaml')['arm']['inertia']


@pytest.fixture(scope='module')
def geometry() -> ArmGeometry:
    return ArmGeometry.from_dict(load_config('arm.yaml')['arm'])


def path_to(frame: str, transforms) -> list:
    """The parent-to-child transforms from base_link down to ``frame``."""
    by_child = {t.child: t for t in transforms}
    path = []
    while frame != BASE_FRAME:
        path.append(by_child[frame])
        frame = by_child[frame].parent
    return path[::-1]


def test_base_to_tip_is_the_rigid_forward_kinematics(geometry) -> None:
    joints = arm_joints(geometry, (0.03, 0.0))
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.uniform(geometry.lower, geometry.upper)
        transforms = moving_transforms(joints, dict(zip(JOINT_NAMES, q))) + fixed_transforms(
            joints)
        translation, rotation = compose(path_to(TIP_FRAME, transforms))
        assert translation[1] == pytest.approx(0.0, abs=1e-12)        # in the x-z plane
        pose = planar_pose(translation, rotation)
        expected = forward(geometry, q)
        np.testing.assert_allclose(pose[:2], expected[:2], atol=1e-12)
        assert math.remainder(pose[2] - expected[2], 2 * math.pi) == pytest.approx(0, abs=1e-12)


def test_planar_poses_map_into_the_x_z_plane_z_up() -> None:
    t = planar_transform(BASE_FRAME, 'p', (1.2, 0.3, math.pi / 2))
    assert t.translation == (1.2, 0.0, 0.3)
    translation, rotation = compose([t])
    np.testing.assert_allclose(rotation.apply([1.0, 0.0, 0.0]), [0.0, 0.0, 1.0], atol=1e-12)
    assert plane.orientation(0.0) == (0.0, -0.0, 0.0, 1.0)


def test_arm_plane_holds_a_planar_pose_as_x_y_with_phi_about_z() -> None:
    """A planar (x, y, phi) in arm_plane, as (x, y, 0) turned by phi about z, is where
    planar_transform puts it in base_link: TipPose (arm_plane) and the scene's base_link
    poses and markers name the same point."""
    to_plane = plane_transform()
    assert (to_plane.parent, to_plane.child) == (BASE_FRAME, 'arm_plane')
    rng = np.random.default_rng(5)
    for x, y, phi in rng.uniform((-2.0, -2.0, -math.pi), (2.0, 2.0, math.pi), (10, 3)):
        in_plane = Transform('arm_plane', 'p', (x, y, 0.0), (0.0, 0.0, math.sin(phi / 2),
                                                               math.cos(phi / 2)))
        translation, rotation = compose([to_plane, in_plane])
        expected, expected_rotation = compose([planar_transform(BASE_FRAME, 'p', (x, y, phi))])
        np.testing.assert_allclose(translation, expected, atol=1e-12)
        np.testing.assert_allclose(rotation.apply([1.0, 0.0, 0.0]),      # the tool axis
                                   expected_rotation.apply([1.0, 0.0, 0.0]), atol=1e-12)
    np.testing.assert_allclose(compose([to_plane])[1].apply([0.0, 0.0, 1.0]),
                               plane.PLANE_NORMAL, atol=1e-12)     # z: the joints' axis


def test_optical_frame_looks_at_the_plate_behind_the_arm(geometry) -> None:
    joints = arm_joints(geometry, (0.03, 0.0))
    transforms = moving_transforms(joints, dict(zip(JOINT_NAMES, (0.0, 0.6, 0.0, 0.0)))
                                   ) + fixed_transforms(joints)
    translation, rotation = compose(path_to(CAMERA_OPTICAL_FRAME, transforms))
    reach = 0.6 + geometry.link3 + geometry.link4
    np.testing.assert_allclose(translation, [reach + 0.03, 0.0, geometry.offset], atol=1e-12)
    np.testing.assert_allclose(rotation.apply([0.0, 0.0, 1.0]), [0, 1, 0], atol=1e-12)  # axis
    np.testing.assert_allclose(rotation.apply([1.0, 0.0, 0.0]), [1, 0, 0], atol=1e-12)  # u
    np.testing.assert_allclose(rotation.apply([0.0, 1.0, 0.0]), [0, 0, -1], atol=1e-12)  # v


def test_missing_joint_positions_are_an_error(geometry) -> None:
    with pytest.raises(ValueError, match='joint3'):
        moving_transforms(arm_joints(geometry), {'joint1': 0.0, 'joint2': 0.5, 'joint4': 0.0})


def test_urdf_has_the_four_joints_with_table_1_limits(geometry) -> None:
    robot = ET.fromstring(robot_description(geometry, INERTIA, (0.03, 0.0)))
    joints = {j.get('name'): j for j in robot.findall('joint')}
    moving = [name for name, j in joints.items() if j.get('type') != 'fixed']
    assert moving == list(JOINT_NAMES)
    assert [joints[n].get('type') for n in moving] == ['revolute', 'prismatic', 'revolute',
                                                       'revolute']
    for i, name in enumerate(JOINT_NAMES):
        limit = joints[name].find('limit')
        assert float(limit.get('lower')) == pytest.approx(geometry.lower[i])
        assert float(limit.get('upper')) == pytest.approx(geometry.upper[i])
        assert float(limit.get('velocity')) == pytest.approx(geometry.velocity[i])
    links = {link.get('name') for link in robot.iter('link')}
    assert {BASE_FRAME, TIP_FRAME, 'tip_camera_link', CAMERA_OPTICAL_FRAME} <= links
    assert all(j.find('parent').get('link') in links and j.find('child').get('link') in links
               for j in joints.values())


def test_urdf_links_carry_the_nominal_masses_where_the_gravity_model_puts_them(geometry) -> None:
    robot = ET.fromstring(robot_description(geometry, INERTIA))
    inertial = {link.get('name'): link.find('inertial') for link in robot.iter('link')
                if link.find('inertial') is not None}
    assert set(inertial) == {'link1', 'link2', 'link3', 'link4'}
    mass = {name: float(e.find('mass').get('value')) for name, e in inertial.items()}
    assert sum(mass.values()) == pytest.approx(sum(INERTIA['masses'].values()))
    m = INERTIA['masses']
    assert mass['link4'] == pytest.approx(m['fourth_arm'] + m['end_effector'])
    centre = float(inertial['link4'].find('origin').get('xyz').split()[0])
    tip = geometry.link4 + INERTIA['end_effector_com']
    assert centre == pytest.approx((m['fourth_arm'] * geometry.link4 / 2
                                    + m['end_effector'] * tip) / mass['link4'])
    for e in inertial.values():
        tensor = e.find('inertia')
        assert all(float(tensor.get(k)) > 0 for k in ('ixx', 'iyy', 'izz'))
