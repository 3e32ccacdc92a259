"""The URDF feeds a simulator, a planner and ros2_control: every massive link can collide, every
joint has an effort limit (held against the gravity model in flexarm_control's tests), the
``<ros2_control>`` system and config/controllers.yaml name the joints of config/arm.yaml."""
import xml.etree.ElementTree as ET

import pytest

from flexarm_core.kinematics import JOINT_NAMES, ArmGeometry
from flexarm_core.params import config_path, load_config, load_node_params
from flexarm_description.urdf_model import (
    MOCK_HARDWARE,
    SYSTEM_NAME,
    robot_description,
)

ARM = load_config('arm.yaml')['arm']
INERTIA = ARM['inertia']
CONTROLLERS = config_path('controllers.yaml')


@pytest.fixture(scope='module')
def geometry() -> ArmGeometry:
    return ArmGeometry.from_dict(ARM)


@pytest.fixture(scope='module')
def robot(geometry) -> ET.Element:
    return ET.fromstring(robot_description(geometry, INERTIA, (0.03, 0.0)))


def moving(robot: ET.Element) -> dict[str, ET.Element]:
    """The URDF's own non-fixed joints (not those of its <ros2_control> block)."""
    return {j.get('name'): j for j in robot.findall('joint') if j.get('type') != 'fixed'}


def test_every_link_with_mass_or_a_shape_can_collide(robot) -> None:
    links = {link.get('name'): link for link in robot.findall('link')}
    massive = {name for name, link in links.items() if link.find('inertial') is not None}
    assert massive == {'link1', 'link2', 'link3', 'link4'}
    for name, link in links.items():
        if name in massive or link.find('visual') is not None:
            collisions = link.findall('collision')
            assert collisions, name
            for collision in collisions:
                size = [float(v) for v in collision.find('geometry/box').get('size').split()]
                assert len(size) == 3 and min(size) > 0, name
    end = [float(c.find('origin').get('xyz').split()[0]) for c in links['link4'].findall(
        'collision')]
    assert max(end) == pytest.approx(ARM['link4'] + INERTIA['end_effector_com'])  # the tool


def test_joints_have_efforts_and_arm_yaml_speeds(robot, geometry) -> None:
    joints = moving(robot)
    assert list(joints) == list(JOINT_NAMES)
    for i, name in enumerate(JOINT_NAMES):
        limit = joints[name].find('limit')
        assert float(limit.get('effort')) > 0
        assert float(limit.get('velocity')) == ARM['velocity'][i]
        assert (float(limit.get('lower')), float(limit.get('upper'))) == (ARM['lower'][i],
                                                                           ARM['upper'][i])


def test_ros2_control_system_commands_positions_within_the_limits(robot) -> None:
    systems = robot.findall('ros2_control')
    assert len(systems) == 1
    system = systems[0]
    assert (system.get('name'), system.get('type')) == (SYSTEM_NAME, 'system')
    assert system.findtext('hardware/plugin') == MOCK_HARDWARE
    joints = system.findall('joint')
    assert [j.get('name') for j in joints] == ARM['joint_names']
    for joint, limit in zip(joints, (j.find('limit') for j in moving(robot).values())):
        commands = joint.findall('command_interface')
        assert [c.get('name') for c in commands] == ['position']
        params = {p.get('name'): float(p.text) for p in commands[0].findall('param')}
        assert params == {'min': float(limit.get('lower')), 'max': float(limit.get('upper'))}
        states = joint.findall('state_interface')
        assert [s.get('name') for s in states] == ['position', 'velocity']
        start = float(states[0].find("param[@name='initial_value']").text)
        assert params['min'] <= start <= params['max']


def test_another_hardware_plugin_or_none(geometry) -> None:
    real = ET.fromstring(robot_description(geometry, INERTIA, hardware='site_arm/ArmSystem'))
    assert real.findtext('ros2_control/hardware/plugin') == 'site_arm/ArmSystem'
    assert ET.fromstring(robot_description(geometry, INERTIA, hardware='')).find(
        'ros2_control') is None
    shipped = load_config('description.yaml', node_name='flexarm_state_publisher')
    assert shipped['hardware_plugin'] == MOCK_HARDWARE


def test_controllers_yaml_names_the_ros2_controllers_and_the_arm_joints() -> None:
    manager = load_node_params(CONTROLLERS, 'controller_manager')
    assert manager['update_rate'] > 0
    assert {name: c['type'] for name, c in manager.items() if isinstance(c, dict)} == {
        'joint_state_broadcaster': 'joint_state_broadcaster/JointStateBroadcaster',
        'forward_position_controller': 'forward_command_controller/ForwardCommandController',
        'joint_trajectory_controller': 'joint_trajectory_controller/JointTrajectoryController'}
    forward = load_node_params(CONTROLLERS, 'forward_position_controller')
    assert forward == {'joints': ARM['joint_names'], 'interface_name': 'position'}
    trajectory = load_node_params(CONTROLLERS, 'joint_trajectory_controller')
    assert trajectory['joints'] == ARM['joint_names']
    assert trajectory['command_interfaces'] == ['position']
    assert trajectory['state_interfaces'] == ['position', 'velocity']
    constraints = trajectory['constraints']
    assert constraints['goal_time'] > 0 and constraints['stopped_velocity_tolerance'] > 0
    arrived = load_config('motion.yaml')['motion']['arrival_tolerance']
    assert [constraints[n]['goal'] for n in ARM['joint_names']] == arrived
    # the tolerances the flexarm nodes' goals carry, for clients that give none
    assert [constraints[n]['trajectory'] for n in ARM['joint_names']] == (
        ARM['trajectory_tolerance']['path'])
    assert constraints['goal_time'] == ARM['trajectory_tolerance']['goal_time']
