"""Vision node as its own process: rendered images in, /tip_pose out."""
import dataclasses
import math

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from rclpy.serialization import serialize_message
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Header

from flexarm_control import topics
from flexarm_control.params import load_config
from flexarm_msgs.msg import TipPose
from flexarm_sim.camera import CameraRenderer
from flexarm_vision.camera_model import Intrinsics
from flexarm_vision.vision_node import image_to_array, info_mismatch, without_stamp

POSE = np.array([1.35, -0.25, -0.6])
CAMERA = load_config('camera.yaml')


def camera_info(i: Intrinsics) -> CameraInfo:
    return CameraInfo(width=i.width, height=i.height, distortion_model='plumb_bob',
                      d=list(i.distortion), k=[i.fx, 0.0, i.cx, 0.0, i.fy, i.cy, 0.0, 0.0, 1.0])


def test_camera_info_check() -> None:
    i = CameraRenderer.from_dict(CAMERA).intrinsics
    assert info_mismatch(camera_info(i), i) == ''
    info = camera_info(i)
    info.k[0] += 1.0
    info.width = 320
    problem = info_mismatch(info, i)
    assert 'fx' in problem and 'width' in problem


def test_image_message_conversion() -> None:
    padded = np.arange(6 * 4, dtype=np.uint8).reshape(4, 6)       # step 6 > width 5
    image, reason = image_to_array(Image(height=4, width=5, encoding='mono8', step=6,
                                         data=padded.tobytes()))
    assert reason == '' and np.array_equal(image, padded[:, :5])
    image, reason = image_to_array(Image(height=4, width=5, encoding='rgb8', step=15,
                                         data=bytes(60)))
    assert image is None and 'rgb8' in reason
    image, reason = image_to_array(Image(height=4, width=5, encoding='mono8', step=5,
                                         data=bytes(7)))
    assert image is None and '7 bytes' in reason


def test_joint_states_compare_without_their_stamp() -> None:
    def raw(sec: int, position: float, velocity: float = 0.0) -> bytes:
        return serialize_message(JointState(
            header=Header(stamp=Time(sec=sec, nanosec=7), frame_id='base_link'),
            name=['joint1', 'joint2'], position=[position, 0.6], velocity=[velocity, 0.0]))

    assert without_stamp(raw(1, 0.1)) == without_stamp(raw(2, 0.1))
    assert without_stamp(raw(1, 0.1)) != without_stamp(raw(1, 0.1 + 1e-12))
    assert without_stamp(raw(1, 0.1)) != without_stamp(raw(1, 0.1, velocity=0.2))


@pytest.mark.node
def test_vision_node_measures_the_rendered_pose(ros_node, launch, wait_for) -> None:
    renderer = CameraRenderer.from_dict(CAMERA)
    rng = np.random.default_rng(0)
    received: list[TipPose] = []
    ros_node.create_subscription(TipPose, topics.TIP_POSE, received.append, 10)
    image_pub = ros_node.create_publisher(Image, topics.CAMERA_IMAGE, 5)
    info_pub = ros_node.create_publisher(CameraInfo, topics.CAMERA_INFO, 1)
    joints_pub = ros_node.create_publisher(JointState, topics.JOINT_STATES, 10)
    black = {'on': False}
    intrinsics = {'published': renderer.intrinsics}

    def publish() -> None:
        stamp = ros_node.get_clock().now().to_msg()
        joints_pub.publish(JointState(header=Header(stamp=stamp),
                                      name=['joint1', 'joint2', 'joint3', 'joint4'],
                                      position=[0.0] * 4, velocity=[0.0] * 4))
        pixels = (np.zeros((480, 640), np.uint8) if black['on']
                  else renderer.render(POSE, rng=rng))
        image_pub.publish(Image(header=Header(stamp=stamp), height=480, width=640,
                                encoding='mono8', step=640, data=pixels.tobytes()))
        info_pub.publish(camera_info(intrinsics['published']))

    ros_node.create_timer(0.1, publish)
    launch('flexarm_vision', use_sim_time=False)

    def settled_pose() -> TipPose | None:
        return next((m for m in reversed(received) if m.valid and m.settled), None)

    msg = wait_for(settled_pose, 30.0, 'a valid, settled /tip_pose')
    assert msg.header.frame_id == 'base_link' and msg.status == ''
    assert math.hypot(msg.pose.x - POSE[0], msg.pose.y - POSE[1]) < 0.2e-3
    assert abs(math.degrees(msg.pose.phi - POSE[2])) < 0.01
    assert msg.holes_used >= 12 and 0 < msg.residual < 0.05e-3

    black['on'] = True
    count = len(received)

    def invalid() -> TipPose | None:
        return next((m for m in received[count:] if not m.valid), None)

    msg = wait_for(invalid, 10.0, 'an invalid /tip_pose for a black image')
    assert 'too dark' in msg.status and not msg.settled and math.isnan(msg.pose.x)

    intrinsics['published'] = dataclasses.replace(renderer.intrinsics,
                                                  fx=renderer.intrinsics.fx + 5.0)
    black['on'] = False
    count = len(received)

    def info_refused() -> TipPose | None:
        return next((m for m in received[count:] if 'camera_info' in m.status), None)

    msg = wait_for(info_refused, 10.0, 'an invalid /tip_pose for a mismatched camera_info')
    assert not msg.valid and 'fx' in msg.status and math.isnan(msg.pose.x)
    intrinsics['published'] = renderer.intrinsics
    count = len(received)
    wait_for(lambda: next((m for m in received[count:] if m.valid), None), 10.0,
             'a valid /tip_pose once camera_info agrees again')
