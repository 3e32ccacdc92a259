"""Node-level: the graph is visible in the ROS tools — the robot model on /robot_description,
the frames on /tf and /tf_static following /joint_states with the rigid model, the scene
markers, and every node's health on /diagnostics; its bag is in one time, the sim's, and
/tip_pose (arm_plane) and /scene/measured_tip (base_link) are the same point through /tf."""
import signal
import threading
import time
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import QoSDurabilityPolicy, QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from flexarm_cli import main
from flexarm_core import topics
from flexarm_core.frames import CALIBRATED_CAMERA_FRAME, PLANE_FRAME
from flexarm_core.kinematics import JOINT_NAMES, ArmGeometry, forward
from flexarm_core.params import load_config
from flexarm_core.ros.stamps import to_ns
from flexarm_core.ros.taken import Taken
from flexarm_description.chain import TIP_FRAME, Transform, compose, planar_pose
from flexarm_msgs.msg import DeflectionSample, PlanarPose
from flexarm_recording.bag_tools import read_decoded
from flexarm_recording.results.outcome_text import Exit
from flexarm_test_support.stamp_order import backwards_steps, beyond_sent, header_stamps
from flexarm_test_support.tf_listening import STATIC_TF_QOS
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
    ros_node.create_subscription(TFMessage, topics.TF_STATIC, keep('static'), STATIC_TF_QOS)
    ros_node.create_subscription(TFMessage, topics.TF, keep('tf'), 100)
    ros_node.create_subscription(JointState, topics.JOINT_STATES, keep('joints'), 100)
    ros_node.create_subscription(DiagnosticArray, '/diagnostics', keep('diagnostics'), 50)
    ros_node.create_subscription(MarkerArray, topics.SCENE_MARKERS, keep('markers'), latched)
    started = {}
    for name in NODES:
        started[name] = launch(name, **{'flexarm_sim': {'real_time_factor': 5.0},
                        'flexarm_learner': {'data_directory': str(tmp_path / 'data'),
                                            'model_directory': str(tmp_path / 'models')},
                        'flexarm_recorder': {'bag_directory': str(tmp_path / 'bags'),
                                             'bag_name': 'visible'}}.get(name, {}))
    geometry = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])

    description = wait_for(lambda: got['description'], 60.0, '/robot_description')[0]
    assert main(['urdf', str(tmp_path / 'flexarm.urdf')]) == Exit.OK      # no graph needed
    assert description.data == (tmp_path / 'flexarm.urdf').read_text()
    robot = ET.fromstring(description.data)
    limits = {j.get('name'): j.find('limit') for j in robot.findall('joint')
              if j.get('type') != 'fixed'}
    assert list(limits) == list(JOINT_NAMES)
    for i, name in enumerate(JOINT_NAMES):
        assert float(limits[name].get('lower')) == pytest.approx(geometry.lower[i])
        assert float(limits[name].get('upper')) == pytest.approx(geometry.upper[i])

    def static_frames() -> dict[str, Transform]:
        """The fixed frames of every /tf_static publisher (the state publisher's, the vision
        node's calibrated camera), once both have published."""
        with lock:
            frames = {t.child_frame_id: as_transform(t) for m in got['static']
                      for t in m.transforms}
        return frames if {TIP_FRAME, CALIBRATED_CAMERA_FRAME} <= set(frames) else {}

    static = wait_for(static_frames, 30.0, '/tf_static of the state publisher and vision')
    assert static[CALIBRATED_CAMERA_FRAME].parent == TIP_FRAME

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
    by_child = {**static, **{t.child: t for t in map(as_transform, tf.transforms)}}
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

    # A learning sample, stamped in sim time as the learner does: the scene shows it at then.
    samples = ros_node.create_publisher(DeflectionSample, topics.SAMPLES, 10)
    stamp = got['joints'][-1].header.stamp

    def sample_shown():
        samples.publish(DeflectionSample(stamp=stamp, measured_pose=PlanarPose(x=1.4, y=-0.3)))
        with lock:
            return any(m.ns == 'samples' for m in got['markers'][-1].markers)

    wait_for(sample_shown, 30.0, 'the sample on /scene/markers')

    def timed() -> set[str]:
        """The nodes whose /diagnostics have been stamped with a time (not 0)."""
        with lock:
            return {s.name.split(':')[0] for a in got['diagnostics']
                    if a.header.stamp.sec or a.header.stamp.nanosec for s in a.status}

    wait_for(lambda: timed() >= set(NODES), 30.0, 'each node\'s /diagnostics stamped')
    recorder = started['flexarm_recorder']
    recorder.signal(signal.SIGINT)
    recorder.process.wait(timeout=30.0)
    check_bag(tmp_path / 'bags' / 'visible',
              clock_published_after(ros_node, time.time_ns(), wait_for))


def clock_published_after(node, wall_ns: int, wait_for) -> int:
    """The stamp [ns] of a /clock the simulator published after ``wall_ns`` (its source
    timestamp, wall clock): the graph's time then, beyond every stamp sent before."""
    clock = node.create_subscription(Clock, topics.CLOCK, lambda _: None, 10,
                                     callback_group=Taken())

    def published_after() -> int | None:
        with clock.handle:
            while (taken := clock.handle.take_message(Clock, False)) is not None:
                msg, info = taken
                if info['source_timestamp'] >= wall_ns:
                    return to_ns(msg.clock)
        return None

    return wait_for(published_after, 30.0, 'a /clock published after the recording ended')


def check_bag(bag, final_ns: int) -> None:
    """One time in the bag: every stream's header stamps in order and none ahead of the
    graph's time when its message was sent (no wall time, nothing from the future:
    stamp_order.beyond_sent, bounded by ``final_ns`` after the last recorded /clock), the
    markers stamped; the measured tip is one point in both frames."""
    recorded = [(topic, msg, raw.publish_time) for topic, msg, raw in read_decoded(bag)]
    messages = [(topic, msg) for topic, msg, _ in recorded]
    assert any(topic == topics.CLOCK for topic, _ in messages), 'no /clock recorded'
    stamps = [s for topic, msg in messages for s in header_stamps(topic, msg)]
    assert {k: n for k, n in backwards_steps(stamps).items() if n} == {}
    ahead = {stream: f'{lead * 1e-9:.3f} s' for stream, lead in beyond_sent(
        recorded, final_ns).items()}
    assert not ahead, f'stamped ahead of the graph\'s time when sent, by: {ahead}'
    last_markers = [m for t, m in messages if t == '/scene/markers'][-1].markers
    assert all(m.header.stamp.sec or m.header.stamp.nanosec for m in last_markers)
    reported = {s.name.split(':')[0] for t, m in messages if t == '/diagnostics'
                and (m.header.stamp.sec or m.header.stamp.nanosec) for s in m.status}
    assert set(NODES) <= reported, 'a node never stamped its diagnostics with a time'

    static = {t.child_frame_id: as_transform(t) for topic, m in messages
              if topic == '/tf_static' for t in m.transforms}
    tips = {(m.header.stamp.sec, m.header.stamp.nanosec): m for t, m in messages
            if t == '/tip_pose' and m.valid}
    assert tips and {m.header.frame_id for m in tips.values()} == {PLANE_FRAME}
    shown = [m for t, m in messages if t == '/scene/measured_tip'
             and (m.header.stamp.sec, m.header.stamp.nanosec) in tips]
    assert shown
    for pose in shown:
        tip = tips[(pose.header.stamp.sec, pose.header.stamp.nanosec)]
        in_plane = Transform(PLANE_FRAME, 'tip', (tip.pose.x, tip.pose.y, 0.0),
                             (0.0, 0.0, np.sin(tip.pose.phi / 2), np.cos(tip.pose.phi / 2)))
        translation, rotation = compose([static[PLANE_FRAME], in_plane])
        assert pose.header.frame_id == static[PLANE_FRAME].parent == 'base_link'
        p, q = pose.pose.position, pose.pose.orientation
        np.testing.assert_allclose(translation, [p.x, p.y, p.z], atol=1e-9)
        shown_rotation = compose([Transform('base_link', 'tip', (0, 0, 0),
                                            (q.x, q.y, q.z, q.w))])[1]
        np.testing.assert_allclose(rotation.apply([1.0, 0.0, 0.0]),     # the tool axis
                                   shown_rotation.apply([1.0, 0.0, 0.0]), atol=1e-9)
