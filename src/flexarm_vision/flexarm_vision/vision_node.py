"""Vision node: tip camera images -> absolute tip pose on ``/tip_pose``.

Subscribes ``/camera/image_raw`` (mono8), ``/camera/camera_info`` (checked against the
configured intrinsics) and ``/joint_states`` (joint stillness); publishes one
``flexarm_msgs/TipPose`` per image, stamped with the image's capture time. The pose comes from
:class:`TipPoseEstimator`; whether the arm was at rest from :class:`SettleDetector`.
An invalid measurement carries NaN coordinates and the reason in ``status``; every image is
invalid while the last camera_info disagrees with config/camera.yaml.
"""
from __future__ import annotations

import math

import numpy as np
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import CameraInfo, Image, JointState

from flexarm_control import topics
from flexarm_control.node_main import run
from flexarm_control.node_params import declare_tree
from flexarm_msgs.msg import PlanarPose, TipPose
from flexarm_vision.camera_model import Intrinsics
from flexarm_vision.pose_estimator import Estimate, TipPoseEstimator
from flexarm_vision.settling import SettleDetector, SettleSettings

BASE_FRAME = 'base_link'
INFO_TOLERANCE = 1e-6     # relative mismatch of camera_info values that is reported
STAMP_END = 12            # serialized message: 4-byte CDR header, then header.stamp (8 bytes)


def image_to_array(msg: Image) -> tuple[np.ndarray | None, str]:
    """mono8 Image -> (height, width) uint8 array, or None and the reason."""
    if msg.encoding != 'mono8':
        return None, f'unsupported image encoding {msg.encoding!r} (expected mono8)'
    if msg.step < msg.width or len(msg.data) < msg.step * msg.height:
        return None, (f'image data of {len(msg.data)} bytes does not hold {msg.height} rows '
                      f'of step {msg.step} >= width {msg.width}')
    rows = np.frombuffer(msg.data, np.uint8, count=msg.step * msg.height)
    return rows.reshape(msg.height, msg.step)[:, :msg.width], ''


def info_mismatch(info: CameraInfo, intrinsics: Intrinsics) -> str:
    """Why ``info`` disagrees with the configured intrinsics ('' if it agrees)."""
    expected = {'width': intrinsics.width, 'height': intrinsics.height, 'fx': intrinsics.fx,
                'fy': intrinsics.fy, 'cx': intrinsics.cx, 'cy': intrinsics.cy}
    got = {'width': info.width, 'height': info.height, 'fx': info.k[0], 'fy': info.k[4],
           'cx': info.k[2], 'cy': info.k[5]}
    distortion = list(info.d) + [0.0] * (len(intrinsics.distortion) - len(info.d))
    for i, (a, b) in enumerate(zip(distortion, intrinsics.distortion)):
        got[f'd[{i}]'], expected[f'd[{i}]'] = a, b
    bad = [f'{k} {got[k]:g} != {v:g}' for k, v in expected.items()
           if not math.isclose(got[k], v, rel_tol=INFO_TOLERANCE, abs_tol=INFO_TOLERANCE)]
    return ', '.join(bad)


def seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def without_stamp(raw: bytes) -> bytes:
    """A serialized message whose first field is a std_msgs/Header, minus its stamp."""
    return raw[STAMP_END:]


class VisionNode(Node):

    def __init__(self) -> None:
        super().__init__('flexarm_vision')
        trees = {key: declare_tree(self, key, 'config/camera.yaml')
                 for key in ('plate', 'camera')}
        trees['vision'] = declare_tree(self, 'vision', 'config/vision.yaml')
        self._estimator = TipPoseEstimator.from_dict(trees)
        self._settle = SettleDetector(SettleSettings.from_dict(
            declare_tree(self, 'settle', 'config/vision.yaml')))
        self._info_problem: str | None = None
        self._pub = self.create_publisher(TipPose, topics.TIP_POSE, 10)
        self.create_subscription(Image, topics.CAMERA_IMAGE, self._on_image,
                                 qos_profile_sensor_data)
        # volatile: matches both a latched (simulator) and a per-frame (driver) camera_info
        self.create_subscription(CameraInfo, topics.CAMERA_INFO, self._on_info, 1)
        # Raw: at a 10x real-time factor /joint_states comes 1000 times a wall second; only
        # a message that differs from the previous one beyond its stamp is parsed (a still
        # arm repeats itself; any move changes the positions and is never missed).
        self._last_joints = b''
        self.create_subscription(JointState, topics.JOINT_STATES, self._on_joints, 10,
                                 raw=True)
        i = self._estimator.camera.intrinsics
        self.get_logger().info(f'estimating the tip pose from {i.width}x{i.height} images of '
                               f'a {self._estimator.plate.shape} hole plate')

    def _on_info(self, msg: CameraInfo) -> None:
        problem = info_mismatch(msg, self._estimator.camera.intrinsics)
        if problem and problem != self._info_problem:
            self.get_logger().warning(f'camera_info differs from config/camera.yaml: {problem}')
        self._info_problem = problem

    def _on_joints(self, raw: bytes) -> None:
        content = without_stamp(raw)
        if content == self._last_joints:
            return
        self._last_joints = content
        msg = deserialize_message(raw, JointState)
        if msg.velocity:
            self._settle.update_joints(seconds(msg.header.stamp), np.asarray(msg.velocity))

    def _on_image(self, msg: Image) -> None:
        image, reason = image_to_array(msg)
        if self._info_problem:
            image = None
            reason = f'camera_info differs from config/camera.yaml: {self._info_problem}'
        estimate = (self._estimator.estimate(image) if image is not None
                    else Estimate(None, False, 0, 0.0, reason))
        unsettled = self._settle.update_estimate(
            seconds(msg.header.stamp), estimate.pose if estimate.valid else None)
        out = TipPose(valid=estimate.valid, settled=estimate.valid and unsettled is None,
                      holes_used=estimate.holes_used, residual=estimate.residual)
        out.header.stamp = msg.header.stamp
        out.header.frame_id = BASE_FRAME
        if estimate.valid:
            x, y, phi = (float(v) for v in estimate.pose)
            out.pose = PlanarPose(x=x, y=y, phi=phi)
            out.status = unsettled or ''
        else:
            out.pose = PlanarPose(x=math.nan, y=math.nan, phi=math.nan)
            out.status = estimate.status
        self._pub.publish(out)


def main(args: list[str] | None = None) -> None:
    run(VisionNode, args)


if __name__ == '__main__':
    main()
