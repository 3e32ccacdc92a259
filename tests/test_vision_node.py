"""Vision node as its own process: rendered images in, /tip_pose out."""
import math

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Header

from flexarm_core import topics
from flexarm_core.health_report import ERROR, OK, STALE, WARN, WindowSummary
from flexarm_core.params import load_config
from flexarm_core.tool_correction import ToolCorrection
from flexarm_msgs.msg import TipPose
from flexarm_sim.camera import CameraRenderer
from flexarm_vision.camera_calibration import CameraCorrection
from flexarm_vision.camera_info import camera_info, info_intrinsics
from flexarm_vision.image_encoding import image_to_array
from flexarm_vision.stored_correction import StoredCorrection
from flexarm_vision.vision_node import (
    calibration_status,
    camera_info_status,
    lens_status,
    lens_warning,
    measurement_status,
    without_stamp,
)

POSE = np.array([1.35, -0.25, -0.6])
CAMERA = load_config('camera.yaml')
# Another camera than config/camera.yaml's: other focal length, principal point and a full
# plumb_bob lens (its driver publishes these in camera_info).
OTHER = {**CAMERA, 'camera': {**CAMERA['camera'], 'fx': CAMERA['camera']['fx'] * 1.04,
                              'fy': CAMERA['camera']['fy'] * 1.03, 'cx': 327.5, 'cy': 233.0,
                              'k1': -0.04, 'k2': 0.01, 'p1': 8e-4, 'p2': -5e-4, 'k3': 0.002}}


def test_camera_info_gives_the_intrinsics_or_why_not() -> None:
    i = CameraRenderer.from_dict(OTHER).intrinsics
    assert i.tangential == (8e-4, -5e-4) and i.k3 == 0.002
    assert info_intrinsics(camera_info(i)) == (i, '')
    info = camera_info(i)
    info.distortion_model = 'equidistant'
    got, reason = info_intrinsics(info)
    assert got is None and 'equidistant' in reason
    info = camera_info(i)
    info.k[1] = 0.5
    got, reason = info_intrinsics(info)
    assert got is None and 'skew' in reason


@pytest.mark.parametrize('encoding', ['rgb8', 'bgr8', 'rgba8', 'bgra8', 'mono16',
                                      'bayer_rggb8', 'bayer_grbg8'])
def test_images_of_other_encodings_measure_like_mono8(encoding: str) -> None:
    from flexarm_vision.pose_estimator import TipPoseEstimator
    estimator = TipPoseEstimator.from_dict({**CAMERA, 'vision': load_config(
        'vision.yaml', node_name='flexarm_vision')['vision']})
    grey = CameraRenderer.from_dict(CAMERA).render(POSE, rng=np.random.default_rng(1))
    if encoding == 'mono16':
        pixels = grey.astype('<u2') * 257
    elif encoding.startswith('bayer'):
        pixels = grey                              # a grey scene: every filter sees the same
    else:
        channels = 4 if encoding.endswith('a8') else 3
        pixels = np.repeat(grey[:, :, None], channels, axis=2)
    data = pixels.tobytes()
    image, reason = image_to_array(Image(height=480, width=640, encoding=encoding,
                                         step=len(data) // 480, data=data))
    assert reason == '' and image.shape == grey.shape and image.dtype == np.uint8
    if not encoding.startswith('bayer'):                 # demosaicing blurs edges a little
        assert np.max(np.abs(image.astype(int) - grey)) <= 1
    estimate = estimator.estimate(image)
    assert estimate.valid and np.hypot(*(estimate.pose[:2] - POSE[:2])) < 0.02e-3


def test_image_message_conversion() -> None:
    padded = np.arange(6 * 4, dtype=np.uint8).reshape(4, 6)       # step 6 > width 5
    image, reason = image_to_array(Image(height=4, width=5, encoding='mono8', step=6,
                                         data=padded.tobytes()))
    assert reason == '' and np.array_equal(image, padded[:, :5])
    big = np.array([[0x1234, 0xFFFF]], '>u2')
    image, reason = image_to_array(Image(height=1, width=2, encoding='mono16', step=4,
                                         is_bigendian=1, data=big.tobytes()))
    assert reason == '' and image.tolist() == [[0x12, 255]]
    image, reason = image_to_array(Image(height=4, width=5, encoding='yuv422', step=10,
                                         data=bytes(40)))
    assert image is None and 'yuv422' in reason
    image, reason = image_to_array(Image(height=4, width=5, encoding='rgb8', step=15,
                                         data=bytes(59)))
    assert image is None and '59 bytes' in reason


def test_joint_states_compare_without_their_stamp() -> None:
    def raw(sec: int, position: float, velocity: float = 0.0) -> bytes:
        return serialize_message(JointState(
            header=Header(stamp=Time(sec=sec, nanosec=7), frame_id='base_link'),
            name=['joint1', 'joint2'], position=[position, 0.6], velocity=[velocity, 0.0]))

    # CDR padding bytes are unspecified (two serializations of one message may differ there:
    # the node then parses a repeat, harmless), so the stamp is replaced in place: the bytes
    # before CDR_STAMP.stop must be the stamp, and all of it.
    first = raw(1, 0.1)
    later = first[:4] + (2).to_bytes(4, 'little') + (9).to_bytes(4, 'little') + first[12:]
    stamp = deserialize_message(later, JointState).header.stamp
    assert (stamp.sec, stamp.nanosec) == (2, 9)
    assert without_stamp(first) == without_stamp(later)
    assert without_stamp(raw(1, 0.1)) != without_stamp(raw(1, 0.1 + 1e-12))
    assert without_stamp(raw(1, 0.1)) != without_stamp(raw(1, 0.1, velocity=0.2))


def test_measurement_health_is_stale_without_images_and_warns_below_half_valid() -> None:
    none = measurement_status('flexarm_vision', '', WindowSummary(0, 0, math.nan, math.nan),
                              10.0, '')
    assert none.level == STALE and none.message == 'no image for 10 s'
    poor = measurement_status('flexarm_vision', 'tip_camera',
                              WindowSummary(50, 20, 12e-6, 30e-6), 10.0, 'too dark')
    assert poor.level == WARN and poor.message == '40 % of 50 images valid, last: too dark'
    assert poor.hardware_id == 'tip_camera'
    good = measurement_status('flexarm_vision', 'tip_camera',
                              WindowSummary(50, 25, 12e-6, 30e-6), 10.0, 'too dark')
    assert good.level == OK
    assert good.message == '50 % of 50 images valid, residual median 0.0120 mm'
    assert dict(good.values) == {'images': '50', 'valid rate [%]': '50',
                                 'residual median [mm]': '0.012', 'residual max [mm]': '0.03',
                                 'last invalid reason': 'too dark'}


def test_camera_info_health_errs_while_refused() -> None:
    i = CameraRenderer.from_dict(CAMERA).intrinsics
    configured = camera_info_status('flexarm_vision', '', i, False, '')
    assert configured.level == OK and configured.message == 'intrinsics from config/camera.yaml'
    assert dict(configured.values)['fx [px]'] == f'{i.fx:.6g}'
    refused = camera_info_status('flexarm_vision', '', i, True, "model 'equidistant' refused")
    assert refused.level == ERROR and refused.message == "model 'equidistant' refused"


def stored(path: str, record: dict | None = None, problem: str = '') -> StoredCorrection:
    """A tool correction as the vision node keeps it, from a file holding ``record`` (or
    damaged: ``problem``)."""
    def read(_: str) -> dict | None:
        if problem:
            raise ValueError(problem)
        return record
    return StoredCorrection(path, read, ToolCorrection())


def test_a_damaged_calibration_file_is_an_error_naming_it() -> None:
    path = '/site/calibration/tool_camera.json'
    held = ToolCorrection(1e-4, 0.0, 0.0)
    fine = calibration_status('flexarm_vision', 'cam', stored(path, {'correction': held}))
    assert fine.level == OK and fine.name == 'flexarm_vision: tool calibration'
    assert fine.message == f'calibrated at an unknown time: {path}' and fine.hardware_id == 'cam'
    made = calibration_status('flexarm_vision', 'cam', stored(path, {
        'correction': held, 'stamp': '2026-11-25T10:00:00', 'reference': '/reference/tip_pose',
        'poses': 6}))
    assert made.message == ('calibrated 2026-11-25T10:00:00 against /reference/tip_pose from 6 '
                            f'poses: {path}')
    none = calibration_status('flexarm_vision', 'cam', stored(path))
    assert none.level == OK and none.message.startswith(f'NOT calibrated (no {path})')
    problem = f'tool calibration {path} is damaged (truncated); run flexarm calibrate again'
    damaged = stored(path, problem=problem)
    assert calibration_status('flexarm_vision', 'cam', damaged).level == ERROR
    assert calibration_status('flexarm_vision', 'cam', damaged).message == (
        f'{problem}; poses are measured without it')
    damaged.set(held)
    set_since = calibration_status('flexarm_vision', 'cam', damaged)
    assert set_since.level == ERROR and set_since.message.endswith('the parameter correction')
    unstored = stored(path, {'correction': held})
    unstored.set(ToolCorrection(2e-4, 0.0, 0.0))
    message = calibration_status('flexarm_vision', 'cam', unstored).message
    assert f'which {path} does not hold' in message
    unstored.set(held)
    assert calibration_status('flexarm_vision', 'cam', unstored).message.startswith('calibrated')
    camera = calibration_status('flexarm_vision', 'cam', StoredCorrection(
        '/site/camera.json', lambda _: None, CameraCorrection()), 'camera')
    assert camera.name == 'flexarm_vision: camera calibration'
    assert camera.message.endswith('run flexarm calibrate --camera')


def test_a_valid_pose_warns_of_a_camera_off_its_calibration() -> None:
    assert lens_warning(None) == '' and lens_warning((1.001, -0.001)) == ''
    assert lens_warning((1.004, 0.0)) == (
        'camera off its calibration (plate scale +0.40 %, radial stretch +0.00 %): run '
        'flexarm calibrate --camera')
    assert 'radial stretch -0.30 %' in lens_warning((1.0, -0.003))


@pytest.mark.node
def test_vision_node_measures_the_rendered_pose(ros_node, launch, wait_for) -> None:
    renderer = CameraRenderer.from_dict(CAMERA)
    rng = np.random.default_rng(0)
    received: list[TipPose] = []
    ros_node.create_subscription(TipPose, topics.TIP_POSE, received.append, 10)
    health: dict[str, DiagnosticStatus] = {}
    ros_node.create_subscription(DiagnosticArray, topics.DIAGNOSTICS, lambda m: health.update(
        {s.name: s for s in m.status}), 10)
    image_pub = ros_node.create_publisher(Image, topics.CAMERA_IMAGE, 5)
    info_pub = ros_node.create_publisher(CameraInfo, topics.CAMERA_INFO, 1)
    joints_pub = ros_node.create_publisher(JointState, topics.JOINT_STATES, 10)
    black = {'on': False}
    camera = {'renderer': renderer, 'encoding': 'mono8', 'model': 'plumb_bob'}

    def publish() -> None:
        stamp = ros_node.get_clock().now().to_msg()
        joints_pub.publish(JointState(header=Header(stamp=stamp),
                                      name=['joint1', 'joint2', 'joint3', 'joint4'],
                                      position=[0.0] * 4, velocity=[0.0] * 4))
        pixels = (np.zeros((480, 640), np.uint8) if black['on']
                  else camera['renderer'].render(POSE, rng=rng))
        if camera['encoding'] == 'rgb8':
            pixels = np.repeat(pixels[:, :, None], 3, axis=2)
        info = camera_info(camera['renderer'].intrinsics)
        info.distortion_model = camera['model']
        info_pub.publish(info)
        image_pub.publish(Image(header=Header(stamp=stamp), height=480, width=640,
                                encoding=camera['encoding'], step=pixels.nbytes // 480,
                                data=pixels.tobytes()))

    ros_node.create_timer(0.1, publish)
    launch('flexarm_vision', use_sim_time=False)

    def settled_pose() -> TipPose | None:
        return next((m for m in reversed(received) if m.valid and m.settled), None)

    msg = wait_for(settled_pose, 30.0, 'a valid, settled /tip_pose')
    assert msg.header.frame_id == 'arm_plane' and msg.status == ''
    assert math.hypot(msg.pose.x - POSE[0], msg.pose.y - POSE[1]) < 0.2e-3
    assert abs(math.degrees(msg.pose.phi - POSE[2])) < 0.01
    assert msg.holes_used >= 12 and 0 < msg.residual < 0.05e-3
    measurements = 'flexarm_vision: measurements'
    wait_for(lambda: measurements in health and health[measurements].level
             == DiagnosticStatus.OK, 10.0, 'measurements OK on /diagnostics')
    assert health['flexarm_vision: camera_info'].message == 'intrinsics from camera_info'

    black['on'] = True
    count = len(received)

    def invalid() -> TipPose | None:
        return next((m for m in received[count:] if not m.valid), None)

    msg = wait_for(invalid, 10.0, 'an invalid /tip_pose for a black image')
    assert 'too dark' in msg.status and not msg.settled and math.isnan(msg.pose.x)

    # Another camera, rgb8, with its own calibration in camera_info: measured through it.
    camera['renderer'], camera['encoding'] = CameraRenderer.from_dict(OTHER), 'rgb8'
    black['on'] = False
    count = len(received)
    msg = wait_for(lambda: next((m for m in received[count + 3:] if m.valid and m.settled),
                                None), 30.0, 'a valid /tip_pose through the other camera')
    assert math.hypot(msg.pose.x - POSE[0], msg.pose.y - POSE[1]) < 0.05e-3
    assert abs(math.degrees(msg.pose.phi - POSE[2])) < 0.01

    camera['model'] = 'equidistant'
    count = len(received)

    def info_refused() -> TipPose | None:
        return next((m for m in received[count:] if 'camera_info' in m.status), None)

    msg = wait_for(info_refused, 10.0, 'an invalid /tip_pose for an unusable camera_info')
    assert not msg.valid and 'equidistant' in msg.status and math.isnan(msg.pose.x)
    wait_for(lambda: health['flexarm_vision: camera_info'].level == DiagnosticStatus.ERROR,
             10.0, 'camera_info ERROR on /diagnostics')
    assert 'equidistant' in health['flexarm_vision: camera_info'].message
    camera['model'] = 'plumb_bob'
    count = len(received)
    wait_for(lambda: next((m for m in received[count:] if m.valid), None), 10.0,
             'a valid /tip_pose once camera_info is usable again')


@pytest.mark.node
def test_images_and_joint_states_are_taken_only_while_someone_wants_tip_poses(
        ros_node, launch, wait_for) -> None:
    health: dict[str, DiagnosticStatus] = {}
    ros_node.create_subscription(DiagnosticArray, topics.DIAGNOSTICS, lambda m: health.update(
        {s.name: s for s in m.status}), 10)
    launch('flexarm_vision', use_sim_time=False)

    def taken(topic: str) -> bool:
        return any(s.node_name == 'flexarm_vision'
                   for s in ros_node.get_subscriptions_info_by_topic(topic))

    measurements = 'flexarm_vision: measurements'
    wait_for(lambda: measurements in health, 30.0, 'the vision node on /diagnostics')
    assert not taken(topics.CAMERA_IMAGE) and not taken(topics.JOINT_STATES)
    assert health[measurements].level == DiagnosticStatus.OK
    assert health[measurements].message == 'idle: no subscriber of /tip_pose'
    wanting = ros_node.create_subscription(TipPose, topics.TIP_POSE, lambda _: None, 10)
    wait_for(lambda: taken(topics.CAMERA_IMAGE) and taken(topics.JOINT_STATES), 10.0,
             'the vision node to subscribe to images and joint states')
    ros_node.destroy_subscription(wanting)
    wait_for(lambda: not taken(topics.CAMERA_IMAGE) and not taken(topics.JOINT_STATES), 10.0,
             'the vision node to drop them')


def test_the_camera_model_status_warns_when_the_plate_shows_the_calibration_is_off() -> None:
    assert lens_status('flexarm_vision', 'cam', None).message == 'no valid image yet'
    careful = lens_status('flexarm_vision', 'cam', (1.001, -0.0008))
    assert careful.level == OK and careful.message.startswith('plate scale +0.10 %')
    refocused = lens_status('flexarm_vision', 'cam', (1.005, 0.0))
    assert refocused.level == WARN and 'poses are still measured' in refocused.message
    assert dict(refocused.values) == {'plate scale': '1.005', 'radial stretch': '0'}
    assert lens_status('flexarm_vision', 'cam', (1.0, -0.004)).level == WARN
