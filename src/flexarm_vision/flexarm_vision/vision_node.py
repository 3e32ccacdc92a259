"""Vision node: tip camera images -> absolute tip pose on ``/tip_pose``.

Subscribes ``/camera/image_raw`` (mono8, mono16, rgb8, bgr8, rgba8, bgra8 or Bayer 8-bit:
:mod:`.image_encoding`), ``/camera/camera_info`` and ``/joint_states`` (joint stillness);
publishes one ``flexarm_msgs/TipPose`` per image, stamped with the image's capture time. The
pose comes from :class:`TipPoseEstimator`; whether the arm was at rest from
:class:`SettleDetector`. An invalid measurement carries NaN coordinates and the reason in
``status``.

On demand (:mod:`flexarm_control.demand`): images and joint states are subscribed only while
``/tip_pose`` has a subscriber — a node that measures (the learner and the compensator
subscribe for a measurement only), the state publisher while someone watches ``/tf``, a
recorder, a viewer. Otherwise nothing is received or estimated, and the simulator renders no
image. Each start of measuring begins a new settle detection: stillness seen before is no
evidence about the arm now. Of the images only the newest is kept: a frame that waited
behind others would report the tip late.

Intrinsics: the camera's calibration as its driver publishes it wins. config/camera.yaml gives
the mounting (standoff, offset) and the intrinsics used until the first camera_info; a
camera_info with other values (K, plumb_bob D up to k3, size) replaces them, with one log line
per change. A camera_info the model cannot use (another distortion model, skew) makes every
image invalid, with the reason, until a usable one comes.

Tool calibration: the reported pose is the tool's, through ``tool_correction`` [axial m,
lateral m, angle rad] (:class:`~flexarm_control.tool_calibration.ToolCorrection`: the camera's
error in the tool frame, measured against a reference by ``flexarm calibrate``). Its value
comes from the site's calibration file (``tool_calibration_file``, written by ``flexarm
calibrate``) when there is one, else zeros; ``flexarm calibrate`` also sets the parameter on
the running node. A damaged file is reported, in the log and as an ERROR on ``/diagnostics``
(which ``flexarm status`` and ``flexarm up`` show: a log line alone went unseen while every pose
was off by the camera's error), and the node runs uncorrected.

Health on ``/diagnostics`` (hardware id: the camera's frame id, from its images):
:func:`measurement_status` over the last ``HEALTH_WINDOW`` seconds (:func:`idle_status` while
nobody asks for tip poses), :func:`camera_info_status` and :func:`calibration_status`.
"""
from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.subscription import Subscription
from sensor_msgs.msg import CameraInfo, Image, JointState

from flexarm_control import topics
from flexarm_control.demand import Demand, on_matched
from flexarm_control.diagnostics import DiagnosticsPublisher
from flexarm_control.health_report import (
    ERROR,
    OK,
    STALE,
    WARN,
    RecentWindow,
    Status,
    WindowSummary,
    status,
)
from flexarm_control.node_main import run
from flexarm_control.node_params import declare, declare_tree
from flexarm_control.paths import repo_path
from flexarm_control.tool_calibration import ToolCorrection, read_calibration
from flexarm_msgs.msg import PlanarPose, TipPose
from flexarm_vision.camera_model import Intrinsics
from flexarm_vision.image_encoding import to_mono8, unpack
from flexarm_vision.pose_estimator import Estimate, TipPoseEstimator
from flexarm_vision.settling import SettleDetector, SettleSettings

BASE_FRAME = 'base_link'
DISTORTION_MODELS = ('plumb_bob', '')   # '' with an empty D: an ideal lens
STAMP_END = 12            # serialized message: 4-byte CDR header, then header.stamp (8 bytes)
HEALTH_WINDOW = 10.0      # [s, wall] images the measurement health looks back on
MIN_VALID_RATE = 0.5      # fewer valid images than this: the measurement health warns
# The fit's plate scale and radial stretch beyond these: the camera differs from its
# calibration by more than a careful calibration leaves (0.1 % focal length, k1 0.005)
LENS_SCALE_WARN = 0.002
LENS_RADIAL_WARN = 0.002
NEWEST_IMAGE = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)


def image_to_array(msg: Image) -> tuple[np.ndarray | None, str]:
    """Image -> (height, width) uint8 grey array, or None and the reason."""
    pixels, reason = unpack(bytes(msg.data), msg.encoding, msg.width, msg.height, msg.step,
                            bool(msg.is_bigendian))
    return (None, reason) if pixels is None else (to_mono8(pixels, msg.encoding), '')


def info_intrinsics(info: CameraInfo) -> tuple[Intrinsics | None, str]:
    """The intrinsics a camera_info publishes, or None and why they cannot be used."""
    if info.distortion_model not in DISTORTION_MODELS or (
            not info.distortion_model and len(info.d)):
        return None, (f'camera_info distortion model {info.distortion_model!r} is not '
                      'supported (plumb_bob only)')
    try:
        return Intrinsics.from_k_d(info.width, info.height, list(info.k), list(info.d)), ''
    except ValueError as exc:
        return None, f'camera_info not usable: {exc}'


def seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def without_stamp(raw: bytes) -> bytes:
    """A serialized message whose first field is a std_msgs/Header, minus its stamp."""
    return raw[STAMP_END:]


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
                      'measured, calibrate the camera again', values, camera)
    return status(node, 'camera model', OK, seen, values, camera)


def idle_status(node: str, camera: str) -> Status:
    """``<node>: measurements`` while nobody subscribes to ``/tip_pose``: OK, nothing to do."""
    return status(node, 'measurements', OK, 'idle: no subscriber of /tip_pose',
                  hardware_id=camera)


def calibration_status(node: str, camera: str, path: str, problem: str, in_use: str,
                       record: Mapping[str, Any] | None = None) -> Status:
    """``<node>: tool calibration``: ERROR while the calibration file ``path`` is damaged
    (``problem``: it names the file and the reason), OK otherwise; ``in_use`` says where the
    correction in use came from ('none', 'parameter' or the file), ``record`` what the file
    says of its making (:func:`~flexarm_control.tool_calibration.write_calibration`). The
    message says plainly whether the camera is calibrated: ``up`` and ``status`` show it."""
    values = {'file': path, 'correction from': in_use, 'problem': problem}
    if problem:
        return status(node, 'tool calibration', ERROR, f'{problem}; poses are reported '
                      f'{"uncorrected" if in_use == "none" else f"with the {in_use} correction"}',
                      values, camera)
    if in_use == 'none':
        return status(node, 'tool calibration', OK, f'NOT calibrated (no {path}): poses carry '
                      "the camera's own error in the tool frame; run flexarm calibrate",
                      values, camera)
    if in_use == 'parameter':
        return status(node, 'tool calibration', OK, 'calibrated by its tool_correction '
                      f'parameter, which {path} does not hold: a restart of the node loses it '
                      '(flexarm calibrate writes the file the node reads)', values, camera)
    made = record or {}
    when = made.get('stamp', 'at an unknown time')
    against = f" against {made['reference']}" if made.get('reference') else ''
    poses = f" from {made['poses']} poses" if made.get('poses') else ''
    return status(node, 'tool calibration', OK,
                  f'calibrated {when}{against}{poses}: {path}', values, camera)


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


class VisionNode(Node):

    def __init__(self) -> None:
        super().__init__('flexarm_vision')
        trees = {key: declare_tree(self, key, 'config/camera.yaml')
                 for key in ('plate', 'camera')}
        trees['vision'] = declare_tree(self, 'vision', 'config/vision.yaml')
        self._estimator = TipPoseEstimator.from_dict(trees)
        self._settle = SettleDetector(SettleSettings.from_dict(
            declare_tree(self, 'settle', 'config/vision.yaml')))
        self._configured = self._estimator.camera.intrinsics
        self._correction = ToolCorrection.from_list(declare(
            self, 'tool_correction', self._stored_correction().as_list(),
            "[m, m, rad] the camera's error in the tool frame (axial, lateral, angle), removed "
            'from every pose; default: tool_calibration_file'))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._info_problem = ''
        self._info_used = False       # intrinsics from a camera_info (else config/camera.yaml)
        self._recent = RecentWindow(HEALTH_WINDOW)    # fit residuals of the valid images
        self._last_invalid = ''
        self._lens: tuple[float, float] | None = None   # scale, radial of the last valid fit
        self._camera_id = ''          # the frame id of the camera's images
        # volatile: matches both a latched (simulator) and a per-frame (driver) camera_info
        self.create_subscription(CameraInfo, topics.CAMERA_INFO, self._on_info, 1)
        self._last_joints = b''
        self._inputs: list[Subscription] = []      # images and joint states while measuring
        self._pub = self.create_publisher(TipPose, topics.TIP_POSE, 10, event_callbacks=(
            PublisherEventCallbacks(matched=on_matched(topics.TIP_POSE, Demand(self._measure)))))
        self._diagnostics = DiagnosticsPublisher(self, self.statuses)
        i = self._estimator.camera.intrinsics
        self.get_logger().info(f'estimating the tip pose from {i.width}x{i.height} images of '
                               f'a {self._estimator.plate.shape} hole plate')

    def _stored_correction(self) -> ToolCorrection:
        """The correction of the site's calibration file, zeros without a usable one."""
        self._calibration_file = str(repo_path(declare(
            self, 'tool_calibration_file', 'calibration/tool_camera.json',
            'tool calibration written by flexarm calibrate (relative: to the repository)')))
        record = self._calibration_record = self._read_calibration()
        self._correction_from = 'none' if record is None else self._calibration_file
        if self._calibration_problem:
            self.get_logger().error(f'{self._calibration_problem}; poses are reported '
                                    'uncorrected')
        if record is None:
            return ToolCorrection()
        self.get_logger().info(f'tool calibration from {self._calibration_file}: '
                               f'{record["correction"]}')
        return record['correction']

    def _read_calibration(self) -> dict | None:
        """The calibration file's record (None: none, or damaged: ``_calibration_problem``
        says why)."""
        self._calibration_problem = ''
        try:
            return read_calibration(self._calibration_file)
        except (ValueError, OSError) as exc:
            self._calibration_problem = str(exc)
            return None

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
        """The node's health (module docstring): measurements, camera model, camera_info,
        tool calibration."""
        name = self.get_name()
        return [measurement_status(name, self._camera_id,
                                   self._recent.summary(time.monotonic()), HEALTH_WINDOW,
                                   self._last_invalid) if self._inputs else
                idle_status(name, self._camera_id),
                lens_status(name, self._camera_id, self._lens),
                camera_info_status(name, self._camera_id, self._estimator.camera.intrinsics,
                                   self._info_used, self._info_problem),
                calibration_status(name, self._camera_id, self._calibration_file,
                                   self._calibration_problem, self._correction_from,
                                   self._calibration_record)]

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        for param in params:
            if param.name == 'tool_correction':
                try:
                    self._correction = ToolCorrection.from_list(param.value)
                except (ValueError, TypeError) as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
                self.get_logger().info(f'tool correction now {self._correction}')
                record = self._read_calibration()   # flexarm calibrate has just rewritten it
                stored = record is not None and np.allclose(
                    record['correction'].as_list(), self._correction.as_list(), rtol=0, atol=1e-12)
                self._calibration_record = record if stored else None
                self._correction_from = self._calibration_file if stored else 'parameter'
        return SetParametersResult(successful=True)

    def _on_info(self, msg: CameraInfo) -> None:
        intrinsics, problem = info_intrinsics(msg)
        if problem != self._info_problem and problem:
            self.get_logger().error(problem)
        self._info_problem = problem
        self._info_used = self._info_used or intrinsics is not None
        if intrinsics is None or intrinsics == self._estimator.camera.intrinsics:
            return
        self._estimator = self._estimator.with_camera(
            self._estimator.camera.with_intrinsics(intrinsics))
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
        out.header.frame_id = BASE_FRAME
        if estimate.valid:
            x, y, phi = (float(v) for v in self._correction.pose(estimate.pose))
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
