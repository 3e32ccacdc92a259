"""The calibrations of a running graph's camera: its own parameters from the plate
(``flexarm calibrate --camera``) and its error in the tool frame against a reference
(``flexarm calibrate``, and the first step of ``flexarm demo`` / ``benchmark`` in the realistic
world).

Camera (:func:`calibrate_lens`): the arm moves RIGID to the six Table 10 poses; at each one a
camera image (the arm held still) is decoded against the plate through the intrinsics the
vision node measures with (its ``~/camera_info``), and
:func:`~flexarm_vision.camera_calibration.calibrate_camera` finds what the plate can tell of
what is left (focal length over stand-off, k1, k2). The node's correction plus that is stored
atomically and set on the running vision node (``camera_correction``), which measures through
it from then on. The intrinsics it measures through are also written, atomically, beside the
record as the camera_info YAML a ROS camera driver loads (:func:`camera_info_path`:
``calibration/camera_info.yaml``), for the site's driver to publish them itself. A tool
calibration must follow: the camera's measured poses moved.

Tool:
The arm moves RIGID to the six Table 10 poses; at each one the vision node's measured pose
(averaged, settled) is paired with the mean of 3 poses of the reference instrument (a
``flexarm_msgs/TipPose`` topic: a laser tracker at the tool point on a real site, the
simulator's ground truth here), :func:`~flexarm_control.execution.tool_calibration.
calibrate_against_reference` fits the camera's error in the tool frame, and the correction is
stored atomically and set on the running vision node (``tool_correction``), which reports
every pose through it from then on. Its goals are named ``calibration/<target>/rigid``, so a
bag tells them from the operator's goals. The measurements are taken through the vision node's
current correction, so the new one is the old one plus what is left.

Both hold the arm for their whole run (a claim of kind ``calibrate``; each pose's goal runs
within it): no other motion moves the arm between a pose's move and its measurement, and a
pose measured after the claim ended (``flexarm cancel``) is refused and nothing is stored. The
stored details name the claim (``motion``).
"""
from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from rclpy.qos import DurabilityPolicy, QoSProfile, qos_profile_sensor_data
from sensor_msgs.msg import CameraInfo, Image

from flexarm_bringup.launcher import node_name
from flexarm_control.execution.tool_calibration import (
    ReferenceCalibration,
    calibrate_against_reference,
)
from flexarm_control.ros.client import FlexarmClient
from flexarm_core import topics
from flexarm_core.paper import TABLE_10
from flexarm_core.params import load_config
from flexarm_core.tool_correction import ToolCorrection, write_calibration
from flexarm_motion.ros.arm_claim import ArmBusy
from flexarm_recording.results.trials import trial_name
from flexarm_vision.camera_calibration import (
    CameraCalibration,
    CameraCorrection,
    calibrate_camera,
    write_camera_calibration,
)
from flexarm_vision.camera_info_file import write_camera_info_file
from flexarm_vision.camera_model import Intrinsics
from flexarm_vision.image_encoding import image_to_array
from flexarm_vision.pose_estimator import Estimate, TipPoseEstimator

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def calibrate_tool(client: FlexarmClient, reference_topic: str, path: Path,
                   timeout: float = 120.0, say: Callable[[str], None] = print,
                   ) -> tuple[ToolCorrection, ReferenceCalibration, dict[str, Any]]:
    """Calibrate (module docstring); the new correction, what was found and the details
    stored with it at ``path``."""
    vision = node_name('vision')
    current = ToolCorrection.from_list(client.node_parameter(vision, 'tool_correction'))
    targets = [t.pose for t in TABLE_10]
    say(f'calibrating the camera against {reference_topic}: the arm moves RIGID (uncompensated) '
        f'to the {len(targets)} Table 10 poses')
    done = 0
    problem = ''      # why the last pose gave no measurement: the compensator's words

    def measure(target: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        nonlocal done, problem
        done += 1
        say(f'calibration pose {done}/{len(targets)}: x {target[0] * 1e3:.1f} mm, '
            f'y {target[1] * 1e3:.1f} mm, phi {np.degrees(target[2]):.2f} deg')
        result = client.move_to(*target, mode='rigid', timeout=timeout, motion=motion,
                                trial=trial_name('calibration', TABLE_10[done - 1].name, 'rigid'))
        if result.error_code != 0 or not result.measured:
            problem = result.error_string
            say(f'calibration pose {done}/{len(targets)}: no measurement ({problem})')
            return None
        m = result.measured_pose
        reference = client.poses_from(reference_topic, 3, timeout).mean(axis=0)
        lost = client.arm_held()
        if lost:
            raise ArmBusy(f'calibration pose {done} refused: the arm was not held by this '
                          f'calibration alone ({lost}); nothing stored')
        return np.array([m.x, m.y, m.phi]), reference

    with client.claimed_arm('calibrate', f'tool calibration against {reference_topic} at '
                            f'the {len(targets)} Table 10 poses') as motion:
        try:
            found = calibrate_against_reference(targets, measure)
        except ValueError as exc:          # too few poses measured: say why the camera did not
            raise ValueError(f'{exc}; the last pose without one: {problem}' if problem
                             else str(exc)) from None
    correction = current + found.correction
    details = {'reference': reference_topic, 'poses': found.poses, 'motion': motion,
               'spread': list(found.spread), 'stamp': time.strftime('%Y-%m-%dT%H:%M:%S')}
    write_calibration(path, correction, **details)
    client.set_node_parameter(vision, 'tool_correction', correction.as_list())
    return correction, found, details


def camera_info_path(record: Path) -> Path:
    """The camera_info YAML beside the camera calibration ``record`` (camera.json:
    camera_info.yaml)."""
    return record.with_name(f'{record.stem}_info.yaml')


def calibrate_lens(client: FlexarmClient, path: Path, timeout: float = 120.0,
                   say: Callable[[str], None] = print,
                   ) -> tuple[CameraCorrection, CameraCalibration, dict[str, Any]]:
    """Calibrate the camera from the plate (module docstring); the new correction, what was
    found and the details stored with it at ``path``. ValueError with the reason if the images
    cannot tell it."""
    say('calibrating the camera from the plate: the arm moves RIGID (uncompensated) to the '
        f'{len(TABLE_10)} Table 10 poses, one image at each')
    images, problems = [], []
    with client.claimed_arm('calibrate', 'camera calibration from the plate at the '
                            f'{len(TABLE_10)} Table 10 poses') as motion:
        for n, target in enumerate(TABLE_10, 1):
            result = client.move_to(*target.pose, mode='rigid', timeout=timeout, motion=motion,
                                    trial=trial_name('calibration', target.name, 'camera'))
            if result.error_code != 0:
                problems.append(result.error_string)
                say(f'camera pose {n}/{len(TABLE_10)}: the move failed ({result.error_string})')
                continue
            image = client.messages_from(topics.CAMERA_IMAGE, Image, 1, timeout,
                                         qos=qos_profile_sensor_data, what='images')[0]
            lost = client.arm_held()
            if lost:
                raise ArmBusy(f'camera pose {n} refused: the arm was not held by this '
                              f'calibration alone ({lost}); nothing stored')
            images.append((image, target.pose[2]))
    # what the vision node measures through: the camera's camera_info and its correction
    vision = node_name('vision')
    current = CameraCorrection.from_list(client.node_parameter(vision, 'camera_correction'))
    info = client.messages_from(f'{vision}/camera_info', CameraInfo, 1, timeout,
                                qos=LATCHED, what='camera_info messages')[0]
    estimator = TipPoseEstimator.from_dict({
        **load_config('camera.yaml'), **load_config('vision.yaml', node_name=vision)})
    estimator = estimator.with_camera(estimator.camera.with_intrinsics(
        Intrinsics.from_k_d(info.width, info.height, list(info.k), list(info.d))))
    views, angles = [], []
    for image, angle in images:
        pixels, reason = image_to_array(image)
        matched = estimator.match(pixels) if pixels is not None else Estimate(
            None, False, 0, 0.0, reason)
        if isinstance(matched, Estimate):
            problems.append(f'the image did not decode: {matched.status}')
        else:
            views.append(matched)
            angles.append(angle)
    try:
        found = calibrate_camera(estimator.camera, views, angles)
    except ValueError as exc:
        last = f'; the last pose without one: {problems[-1]}' if problems else ''
        raise ValueError(f'{exc}{last}') from None
    correction = current + found.correction
    info_file = camera_info_path(path)
    details = {'views': found.views, 'holes': found.holes, 'motion': motion,
               'rms_before_px': found.rms_before_px, 'rms_after_px': found.rms_after_px,
               'determined': found.determined, 'not_determined': found.not_determined,
               'camera_info_file': str(info_file), 'stamp': time.strftime('%Y-%m-%dT%H:%M:%S')}
    write_camera_calibration(path, correction, **details)
    # what the vision node measures through from now on, for the site's camera driver
    write_camera_info_file(info_file, found.correction.apply(estimator.camera.intrinsics))
    client.set_node_parameter(vision, 'camera_correction', correction.as_list())
    return correction, found, details
