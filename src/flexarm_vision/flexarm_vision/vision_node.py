"""Vision node: tip camera images -> absolute tip pose on ``/tip_pose``.

Consumes ``/camera/image_raw``, ``/camera/camera_info`` and ``/joint_states``, the images and
joint states only while ``/tip_pose`` has a subscriber (:mod:`flexarm_core.demand`); publishes
one ``flexarm_msgs/TipPose`` per image, stamped with its capture time, in frame ``arm_plane``,
the intrinsics in use on ``~/camera_info`` and the calibrated camera mount on ``/tf_static``.
The pose is :class:`~flexarm_vision.pose_estimator.TipPoseEstimator`'s, stillness
:class:`~flexarm_vision.settling.SettleDetector`'s, and the tool and camera corrections are
:mod:`flexarm_core.tool_correction` and :mod:`flexarm_vision.camera_calibration`, read from the
site's files by :mod:`flexarm_vision.stored_correction`; this node maps ROS to them.

Explained in docs/nodes.md#the-vision-node-flexarm_vision.
"""
from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from geometry_msgs.msg import TransformStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.subscription import Subscription
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Header

from flexarm_core import topics
from flexarm_core.demand import Demand, on_matched
from flexarm_core.frames import CALIBRATED_CAMERA_FRAME, PLANE_FRAME, TIP_FRAME
from flexarm_core.health_report import (
    ERROR,
    OK,
    STALE,
    WARN,
    RecentWindow,
    Status,
    WindowSummary,
    status,
)
from flexarm_core.paths import repo_path
from flexarm_core.ros.diagnostics import DiagnosticsPublisher
from flexarm_core.ros.node_main import run
from flexarm_core.ros.node_params import declare, declare_tree
from flexarm_core.ros.stamps import CDR_STAMP, GraphTime
from flexarm_core.tool_correction import ToolCorrection, read_calibration
from flexarm_description.chain import planar_transform
from flexarm_description.tf_message import transform_msg
from flexarm_msgs.msg import PlanarPose, TipPose
from flexarm_vision.camera_calibration import CameraCorrection, read_camera_calibration
from flexarm_vision.camera_info import camera_info, info_intrinsics
from flexarm_vision.camera_model import Intrinsics
from flexarm_vision.image_encoding import image_to_array
from flexarm_vision.pose_estimator import Estimate, TipPoseEstimator
from flexarm_vision.settling import SettleDetector, SettleSettings
from flexarm_vision.stored_correction import StoredCorrection
from tf2_msgs.msg import TFMessage

HEALTH_WINDOW = 10.0      # [s, wall] images the measurement health looks back on
MIN_VALID_RATE = 0.5      # fewer valid images than this: the measurement health warns
# The fit's plate scale and radial stretch beyond these: the camera differs from its
# calibration by more than a careful calibration leaves (0.1 % focal length, k1 0.005)
LENS_SCALE_WARN = 0.002
LENS_RADIAL_WARN = 0.002
NEWEST_IMAGE = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
CALIBRATE = {'tool': 'flexarm calibrate', 'camera': 'flexarm calibrate --camera'}
UNCALIBRATED = {'tool': "poses carry the camera's own error in the tool frame",
                'camera': 'the camera_info intrinsics are used as they are'}


def seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def without_stamp(raw: bytes) -> bytes:
    """A serialized message whose first field is a std_msgs/Header, minus its stamp."""
    return raw[CDR_STAMP.stop:]


def measurement_status(node: str, camera: str, window: WindowSummary, span: float,
                       last_invalid: str) -> Status:
    """``<node>: measurements`` over the images of the last ``span`` seconds: STALE without
    an image; WARN when fewer than ``MIN_VALID_RATE`` of them gave a valid pose; OK
    otherwise. Values: images, valid rate, median and max fit residual of the valid ones, the
    last invalid image's reason."""
    values = {'images': window.count, 'valid rate [%]': round(100 * window.valid_rate, 1),
              'residual median [mm]': round(window.median * 1e3, 4),
              'residual max [mm]': round(window.maximum * 1e3, 4),
              'last invalid reason': last_invalid}
    if not window.count:
        return status(node, 'measurements', STALE, f'no image for {span:g} s', values, camera)
    rate = f'{100 * window.valid_rate:.0f} % of {window.count} images valid'
    if window.valid_rate < MIN_VALID_RATE:
        return status(node, 'measurements', WARN, f'{rate}, last: {last_invalid}', values,
                      camera)
    return status(node, 'measurements', OK, f'{rate}, residual median '
                  f'{window.median * 1e3:.4f} mm', values, camera)


def lens_warning(lens: tuple[float, float] | None) -> str:
    """What a valid pose's ``status`` says of the camera: '' while the plate looks as the
    calibration says (``lens``: the fit's scale and radial stretch), else how far it is off."""
    if lens is None or (abs(lens[0] - 1) <= LENS_SCALE_WARN
                        and abs(lens[1]) <= LENS_RADIAL_WARN):
        return ''
    return (f'camera off its calibration (plate scale {(lens[0] - 1) * 100:+.2f} %, radial '
            f'stretch {lens[1] * 100:+.2f} %): run flexarm calibrate --camera')


def lens_status(node: str, camera: str, lens: tuple[float, float] | None) -> Status:
    """``<node>: camera model``: how the plate looked in the last valid image against the
    camera's calibration (``lens``: the fit's scale and radial stretch, None before one). WARN
    beyond ``LENS_SCALE_WARN`` / ``LENS_RADIAL_WARN``: poses are still measured (the fit takes
    both), but the calibration no longer describes the camera."""
    if lens is None:
        return status(node, 'camera model', OK, 'no valid image yet', hardware_id=camera)
    scale, radial = lens
    values = {'plate scale': round(scale, 5), 'radial stretch': round(radial, 5)}
    seen = (f'plate scale {(scale - 1) * 100:+.2f} %, radial stretch {radial * 100:+.2f} % '
            'against the calibration')
    if abs(scale - 1) > LENS_SCALE_WARN or abs(radial) > LENS_RADIAL_WARN:
        return status(node, 'camera model', WARN, f'{seen}: the camera (focal length, '
                      'stand-off or lens) is not what camera_info says; poses are still '
                      'measured; run flexarm calibrate --camera', values, camera)
    return status(node, 'camera model', OK, seen, values, camera)


def idle_status(node: str, camera: str) -> Status:
    """``<node>: measurements`` while nobody subscribes to ``/tip_pose``: OK, nothing to do."""
    return status(node, 'measurements', OK, 'idle: no subscriber of /tip_pose',
                  hardware_id=camera)


def calibration_status(node: str, camera: str, stored: StoredCorrection,
                       what: str = 'tool') -> Status:
    """``<node>: <what> calibration``: ERROR while its file is damaged (the problem names the
    file and the reason), OK otherwise, saying plainly whether the camera is calibrated
    (``up`` and ``status`` show it) and where the correction in use came from (none, the
    parameter, or the file, with what the file says of its making)."""
    path, problem, source = stored.path, stored.problem, stored.source
    name, command = f'{what} calibration', CALIBRATE[what]
    values = {'file': path, 'correction from': source, 'correction': str(stored.value.as_list()),
              'problem': problem}
    if problem:
        return status(node, name, ERROR, f'{problem}; poses are measured '
                      f'{"without it" if source == "none" else f"with the {source} correction"}',
                      values, camera)
    if source == 'none':
        return status(node, name, OK, f'NOT calibrated (no {path}): {UNCALIBRATED[what]}; '
                      f'run {command}', values, camera)
    if source == 'parameter':
        return status(node, name, OK, f'calibrated by its {what}_correction parameter, which '
                      f'{path} does not hold: a restart of the node loses it ({command} writes '
                      'the file the node reads)', values, camera)
    made = stored.record or {}
    when = made.get('stamp', 'at an unknown time')
    against = f" against {made['reference']}" if made.get('reference') else ''
    poses = f" from {made['poses']} poses" if made.get('poses') else ''
    return status(node, name, OK, f'calibrated {when}{against}{poses}: {path}', values, camera)


def camera_info_status(node: str, camera: str, intrinsics: Intrinsics, from_info: bool,
                       problem: str) -> Status:
    """``<node>: camera_info``: ERROR while the camera_info is refused (every image is then
    invalid); OK otherwise, saying whether the intrinsics in use come from camera_info or from
    config/camera.yaml (none came yet)."""
    i = intrinsics
    source = 'camera_info' if from_info else 'config/camera.yaml'
    values = {'intrinsics from': source, 'size [px]': f'{i.width}x{i.height}',
              'fx [px]': i.fx, 'fy [px]': i.fy, 'cx [px]': i.cx, 'cy [px]': i.cy,
              'distortion (plumb_bob)': ', '.join(f'{d:g}' for d in i.distortion),
              'refused': problem}
    if problem:
        return status(node, 'camera_info', ERROR, problem, values, camera)
    return status(node, 'camera_info', OK, f'intrinsics from {source}', values, camera)


def calibrated_mount(correction: ToolCorrection, offset: Any) -> TransformStamped:
    """``tip_link`` -> ``tip_camera_calibrated``: the camera where ``correction`` puts it
    (:meth:`~flexarm_core.tool_correction.ToolCorrection.camera_mount` of the nominal mount
    ``offset``), in 3-D as the URDF's frames are; stamp 0, as every static transform of the
    graph (tf2 holds it at every time)."""
    return transform_msg(planar_transform(TIP_FRAME, CALIBRATED_CAMERA_FRAME,
                                          correction.camera_mount(offset)), Header())


class VisionNode(Node):

    def __init__(self) -> None:
        super().__init__('flexarm_vision')
        trees = {key: declare_tree(self, key, 'config/camera.yaml')
                 for key in ('plate', 'camera')}
        trees['vision'] = declare_tree(self, 'vision', 'config/vision.yaml')
        self._estimator = TipPoseEstimator.from_dict(trees)
        self._settle = SettleDetector(SettleSettings.from_dict(
            declare_tree(self, 'settle', 'config/vision.yaml')))
        self._base = self._configured = self._estimator.camera.intrinsics
        self._camera_id = ''          # the frame id of the camera's images
        self._tool = self._stored('tool', read_calibration, ToolCorrection)
        self._lens_fix = self._stored('camera', read_camera_calibration, CameraCorrection)
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._mount = self.create_publisher(TFMessage, topics.TF_STATIC, latched)
        self._publish_mount()
        self._info_pub = self.create_publisher(CameraInfo, '~/camera_info', latched)
        self._use_intrinsics(self._base)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._info_problem = ''
        self._info_used = False       # intrinsics from a camera_info (else config/camera.yaml)
        self._recent = RecentWindow(HEALTH_WINDOW)    # fit residuals of the valid images
        self._last_invalid = ''
        self._lens: tuple[float, float] | None = None   # scale, radial of the last valid fit
        # volatile: matches both a latched (simulator) and a per-frame (driver) camera_info
        self.create_subscription(CameraInfo, topics.CAMERA_INFO, self._on_info, 1)
        self._last_joints = b''
        self._inputs: list[Subscription] = []      # images and joint states while measuring
        self._pub = self.create_publisher(TipPose, topics.TIP_POSE, 10, event_callbacks=(
            PublisherEventCallbacks(matched=on_matched(topics.TIP_POSE, Demand(self._measure)))))
        self._diagnostics = DiagnosticsPublisher(self, self.statuses, stamp=GraphTime(self).stamp)
        i = self._estimator.camera.intrinsics
        self.get_logger().info(f'estimating the tip pose from {i.width}x{i.height} images of '
                               f'a {self._estimator.plate.shape} hole plate')

    def _stored(self, what: str, read: Any, kind: Any) -> StoredCorrection:
        """The ``<what>_correction`` in use (docs/nodes.md): a value other than the neutral one
        given to that parameter, else the ``<what>_calibration_file``'s (the parameter set to
        it), else the neutral one."""
        path = str(repo_path(declare(self, f'{what}_calibration_file', 'config/vision.yaml')))
        stored = StoredCorrection(path, read, kind())
        given = declare(self, f'{what}_correction', 'config/vision.yaml')
        if given != kind().as_list():
            stored.set(kind.from_list(given))
        elif stored.problem:
            self.get_logger().error(f'{stored.problem}; poses are reported without it')
        elif stored.record is not None:
            self.get_logger().info(f'{what} calibration from {path}: {stored.value}')
            self.set_parameters([Parameter(f'{what}_correction', value=stored.value.as_list())])
        return stored

    def _publish_mount(self) -> None:
        self._mount.publish(TFMessage(transforms=[calibrated_mount(
            self._tool.value, self._estimator.camera.offset)]))

    def _use_intrinsics(self, base: Intrinsics) -> None:
        """Estimate through ``base`` (camera_info's, or config/camera.yaml's) as the camera
        correction changes it; publish what is in use on ``~/camera_info``."""
        self._base = base
        intrinsics = self._lens_fix.value.apply(base)
        self._estimator = self._estimator.with_camera(
            self._estimator.camera.with_intrinsics(intrinsics))
        self._info_pub.publish(camera_info(intrinsics, Header(frame_id=self._camera_id)))

    def _measure(self, wanted: bool) -> None:
        """Subscribe the inputs when ``/tip_pose`` gains its first subscriber, drop them when
        it loses its last. Raw joint states: at a 10x real-time factor they come 1000 times a
        wall second; only one that differs from the previous beyond its stamp is parsed (a
        still arm repeats itself; any move changes the positions and is never missed)."""
        for subscription in self._inputs:
            self.destroy_subscription(subscription)
        self._inputs = []
        if wanted:
            self._settle = SettleDetector(self._settle.settings)
            self._last_joints = b''
            self._inputs = [
                self.create_subscription(Image, topics.CAMERA_IMAGE, self._on_image,
                                         NEWEST_IMAGE),
                self.create_subscription(JointState, topics.JOINT_STATES, self._on_joints, 10,
                                         raw=True)]

    def statuses(self) -> list[Status]:
        """The node's health (docs/nodes.md): measurements, camera model, camera_info,
        tool calibration."""
        name = self.get_name()
        return [measurement_status(name, self._camera_id,
                                   self._recent.summary(time.monotonic()), HEALTH_WINDOW,
                                   self._last_invalid) if self._inputs else
                idle_status(name, self._camera_id),
                lens_status(name, self._camera_id, self._lens),
                camera_info_status(name, self._camera_id, self._estimator.camera.intrinsics,
                                   self._info_used, self._info_problem),
                calibration_status(name, self._camera_id, self._tool),
                calibration_status(name, self._camera_id, self._lens_fix, 'camera')]

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        for param in params:
            if param.name not in ('tool_correction', 'camera_correction'):
                continue
            kind = ToolCorrection if param.name == 'tool_correction' else CameraCorrection
            try:
                value = kind.from_list(param.value)
            except (ValueError, TypeError) as exc:
                return SetParametersResult(successful=False, reason=str(exc))
            self.get_logger().info(f'{param.name.replace("_", " ")} now {value}')
            if kind is ToolCorrection:
                self._tool.set(value)       # flexarm calibrate has just rewritten its file
                self._publish_mount()
            else:
                self._lens_fix.set(value)
                self._use_intrinsics(self._base)
        return SetParametersResult(successful=True)

    def _on_info(self, msg: CameraInfo) -> None:
        intrinsics, problem = info_intrinsics(msg)
        if problem != self._info_problem and problem:
            self.get_logger().error(problem)
        self._info_problem = problem
        self._info_used = self._info_used or intrinsics is not None
        if intrinsics is None or intrinsics == self._base:
            return
        self._use_intrinsics(intrinsics)
        source = ('as config/camera.yaml' if intrinsics == self._configured
                  else f'instead of config/camera.yaml\'s {self._configured}')
        self.get_logger().info(f'intrinsics from camera_info: {intrinsics}, {source}')

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
            image, reason = None, self._info_problem
        estimate = (self._estimator.estimate(image) if image is not None
                    else Estimate(None, False, 0, 0.0, reason))
        self._camera_id = msg.header.frame_id
        self._recent.add(time.monotonic(), estimate.residual if estimate.valid else None)
        if not estimate.valid:
            self._last_invalid = estimate.status
        else:
            self._lens = (estimate.scale, estimate.radial)
        unsettled = self._settle.update_estimate(
            seconds(msg.header.stamp), estimate.pose if estimate.valid else None)
        out = TipPose(valid=estimate.valid, settled=estimate.valid and unsettled is None,
                      holes_used=estimate.holes_used, residual=estimate.residual)
        out.header.stamp = msg.header.stamp
        out.header.frame_id = PLANE_FRAME
        if estimate.valid:
            x, y, phi = (float(v) for v in self._tool.value.pose(estimate.pose))
            out.pose = PlanarPose(x=x, y=y, phi=phi)
            out.status = '; '.join(filter(None, (unsettled, lens_warning(self._lens))))
        else:
            out.pose = PlanarPose(x=math.nan, y=math.nan, phi=math.nan)
            out.status = estimate.status
        self._pub.publish(out)


def main(args: list[str] | None = None) -> None:
    run(VisionNode, args)


if __name__ == '__main__':
    main()
