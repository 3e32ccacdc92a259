"""Node-level: the graph is visible in the ROS tools — the robot model on /robot_description,
the frames on /tf and /tf_static following /joint_states with the rigid model, the scene
markers, and every node's health on /diagnostics."""
import threading
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import QoSDurabilityPolicy, QoSProfile
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from flexarm_core import topics
from flexarm_core.kinematics import JOINT_NAMES, ArmGeometry, forward
from flexarm_core.params import load_config
from flexarm_description.chain import TIP_FRAME, Transform, compose, planar_pose
from tf2_msgs.msg import TFMessage

pytestmark = pytest.mark.node

NODES = ('flexarm_sim', 'flexarm_vision', 'flexarm_learner', 'flexarm_compensator',
         'flexarm_state_publisher', 'flexarm_scene', 'flexarm_recorder')


def as_transform(msg) -> Transform:
    t, r = msg.transform.translation, msg.transform.rotation
    return Transform(msg.header.frame_id, msg.child_frame_id, (t.x, t.y, t.z),
                     (r.x, r.y, r.z, r.w))


def chain_to(frame: str, by_child: dict[str, Transform]) -> list[Transform]:
    path = []
    while frame in by_child:
        path.append(by_child[frame])
        frame = by_child[frame].parent
    assert frame == 'base_link', f'{frame} does not lead to base_link'
    return path[::-1]


def test_robot_model_frames_markers_and_diagnostics(launch, ros_node, wait_for, tmp_path):
    latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
    lock = threading.Lock()
    got: dict[str, list] = {'description': [], 'static': [], 'tf': [], 'joints': [],
                            'diagnostics': [], 'markers': []}

    def keep(key):
        def store(msg) -> None:
            with lock:
                got[key] = (got[key] + [msg])[-400:]
        return store

    ros_node.create_subscription(String, topics.ROBOT_DESCRIPTION, keep('description'), latched)
    ros_node.create_subscription(TFMessage, topics.TF_STATIC, keep('static'), latched)
    ros_node.create_subscription(TFMessage, topics.TF, keep('tf'), 100)
    ros_node.create_subscription(JointState, topics.JOINT_STATES, keep('joints'), 100)
    ros_node.create_subscription(DiagnosticArray, '/diagnostics', keep('diagnostics'), 50)
    ros_node.create_subscription(MarkerArray, topics.SCENE_MARKERS, keep('markers'), latched)
    for name in NODES:
        launch(name, **{'flexarm_sim': {'real_time_factor': 5.0},
                        'flexarm_learner': {'data_directory': str(tmp_path / 'data'),
                                            'model_directory': str(tmp_path / 'models')},
                        'flexarm_recorder': {'bag_directory': str(tmp_path / 'bags'),
                                             'bag_name': 'visible'}}.get(name, {}))
    geometry = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])

    description = wait_for(lambda: got['description'], 60.0, '/robot_description')[0]
    robot = ET.fromstring(description.data)
    limits = {j.get('name'): j.find('limit') for j in robot.iter('joint')
              if j.get('type') != 'fixed'}
    assert list(limits) == list(JOINT_NAMES)
    for i, name in enumerate(JOINT_NAMES):
        assert float(limits[name].get('lower')) == pytest.approx(geometry.lower[i])
        assert float(limits[name].get('upper')) == pytest.approx(geometry.upper[i])

    static = wait_for(lambda: got['static'], 30.0, '/tf_static')[0]

    def matched():
        """A /tf of the four joints and the /joint_states it was computed from."""
        with lock:
            states = {(m.header.stamp.sec, m.header.stamp.nanosec): m for m in got['joints']}
            for tf in reversed(got['tf']):
                stamp = tf.transforms[0].header.stamp
                if len(tf.transforms) == 4 and (stamp.sec, stamp.nanosec) in states:
                    return tf, states[(stamp.sec, stamp.nanosec)]
        return None

    tf, state = wait_for(matched, 30.0, 'a /tf message matching a /joint_states message')
    by_child = {t.child: t for t in map(as_transform, [*static.transforms, *tf.transforms])}
    pose = planar_pose(*compose(chain_to(TIP_FRAME, by_child)))
    q = np.array([dict(zip(state.name, state.position))[n] for n in JOINT_NAMES])
    np.testing.assert_allclose(pose, forward(geometry, q), atol=1e-9)
    assert {'tip_camera_link', 'tip_camera_optical_frame'} <= set(by_child)

    def frame_seen(frame: str):
        with lock:
            return any(t.child_frame_id == frame for m in got['tf'] for t in m.transforms)

    wait_for(lambda: frame_seen('tip_true'), 30.0, 'the true tip frame on /tf')
    wait_for(lambda: frame_seen('tip_measured'), 60.0, 'the measured tip frame on /tf')

    markers = wait_for(lambda: got['markers'], 30.0, '/scene/markers')[-1].markers
    assert sum(m.ns == 'regions' for m in markers) == 2

    def reporting() -> set[str]:
        with lock:
            names = {s.name.split(':')[0] for a in got['diagnostics'] for s in a.status}
        return names if names >= set(NODES) else set()

    wait_for(reporting, 30.0, f'/diagnostics from each of {", ".join(NODES)}')
