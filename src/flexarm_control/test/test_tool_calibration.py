"""Tool correction: fitted against a reference it removes the camera's tool-frame error; the
joint-4 sweep's arc gives the reported point's offset relative to the joint-4 axis."""
import math

import numpy as np
import pytest

from flexarm_control.execution.tool_calibration import (
    calibrate_against_reference,
    fit_reference,
    joint4_sweep,
    sweep_joints,
)
from flexarm_core.kinematics import ArmGeometry
from flexarm_core.measurement import Measurement
from flexarm_core.params import load_config
from flexarm_core.tool_correction import ToolCorrection, read_calibration, write_calibration


@pytest.fixture(scope='module')
def geometry():
    return ArmGeometry.from_dict(load_config('arm.yaml')['arm'])


def arc(geometry, joints, wrist, offset):
    """Poses reported by a camera ``offset`` (axial, lateral) off the tool point."""
    poses = []
    for q in joints:
        phi = 0.3 + q[3]
        c, s = math.cos(phi), math.sin(phi)
        ax, lat = geometry.link4 + offset[0], offset[1]
        poses.append([wrist[0] + c * ax - s * lat, wrist[1] + s * ax + c * lat, phi])
    return np.array(poses)


def test_a_sweep_about_a_fixed_axis_gives_the_offset_and_removes_it(geometry):
    joints = sweep_joints(np.array([0.1, 0.6, -0.4, 0.2]), geometry)
    assert joints.shape == (9, 4) and np.ptp(joints[:, 3]) == pytest.approx(0.5)
    assert np.all(joints[:, :3] == [0.1, 0.6, -0.4])
    poses = arc(geometry, joints, (1.2, -0.3), (1.3e-4, -0.9e-4))
    offset = joint4_sweep(joints, poses, geometry)
    assert (offset.axial, offset.lateral) == pytest.approx((1.3e-4, -0.9e-4), abs=1e-9)
    corrected = offset.apply(Measurement(poses[4], np.zeros(3), 3, 12, 0.0)).pose
    np.testing.assert_allclose(corrected, arc(geometry, joints[4:5], (1.2, -0.3), (0, 0))[0],
                               atol=1e-12)
    assert ToolCorrection().apply(Measurement(poses[0], np.zeros(3), 3, 12, 0.0)).pose \
        .tolist() == poses[0].tolist()


def test_the_sweep_stays_inside_joint_4_limits(geometry):
    at_limit = np.array([0.0, 0.6, 0.0, geometry.upper[3] - 0.1])
    sweep = sweep_joints(at_limit, geometry)
    assert sweep[:, 3].max() == geometry.upper[3]


def test_a_sweep_too_short_or_moving_other_joints_is_refused(geometry):
    joints = sweep_joints(np.array([0.1, 0.6, -0.4, 0.2]), geometry, span=0.05)
    with pytest.raises(ValueError, match='3 poses or more over 0.1 rad'):
        joint4_sweep(joints, arc(geometry, joints, (1.2, -0.3), (0, 0)), geometry)
    joints = sweep_joints(np.array([0.1, 0.6, -0.4, 0.2]), geometry)
    joints[2, 0] += 0.01
    with pytest.raises(ValueError, match='hold joints 1 to 3'):
        joint4_sweep(joints, arc(geometry, joints, (1.2, -0.3), (0, 0)), geometry)


def test_a_reference_fit_finds_and_removes_the_tool_frame_error():
    rng = np.random.default_rng(3)
    truth = np.column_stack([rng.uniform(1.0, 1.6, 8), rng.uniform(-0.5, 0.2, 8),
                             rng.uniform(-1.8, 0.0, 8)])
    error = ToolCorrection(1.3e-4, -0.9e-4, 3.5e-4)
    c, s = np.cos(truth[:, 2]), np.sin(truth[:, 2])
    measured = np.column_stack([truth[:, 0] + c * error.axial - s * error.lateral,
                                truth[:, 1] + s * error.axial + c * error.lateral,
                                truth[:, 2] + error.angle])
    fitted = fit_reference(measured, truth)
    assert fitted.as_list() == pytest.approx(error.as_list(), abs=1e-12)
    for m, t in zip(measured, truth):
        np.testing.assert_allclose(fitted.pose(m), t, atol=1e-12)
    assert (fitted + ToolCorrection(1e-5, 0.0, 0.0)).axial == pytest.approx(1.4e-4)
    with pytest.raises(ValueError, match='as many reference'):
        fit_reference(measured, truth[:3])


def test_a_correction_is_three_finite_values():
    assert ToolCorrection.from_list([1e-4, 0, 2e-4]) == ToolCorrection(1e-4, 0.0, 2e-4)
    for bad in ([1e-4, 0.0], [float('nan'), 0.0, 0.0]):
        with pytest.raises(ValueError, match='3 finite values'):
            ToolCorrection.from_list(bad)


def test_the_procedure_fits_the_poses_both_measured_and_reports_their_spread():
    error = ToolCorrection(1e-4, -1e-4, 2e-4)
    targets = [np.array([1.0 + 0.1 * k, -0.2, -0.3 * k]) for k in range(5)]

    def measure(target):
        if target[0] > 1.35:
            return None                                        # the camera saw nothing
        wobble = 1e-5 if target[0] == 1.0 else 0.0             # one pose 10 um off
        truth = target.copy()
        measured = truth.copy()
        c, s = np.cos(truth[2]), np.sin(truth[2])
        measured[:2] += [c * (error.axial + wobble) - s * error.lateral,
                         s * (error.axial + wobble) + c * error.lateral]
        measured[2] += error.angle
        return measured, truth

    found = calibrate_against_reference(targets, measure)
    assert found.poses == 4
    assert found.correction.axial == pytest.approx(1e-4 + 1e-5 / 4, abs=1e-12)
    assert found.spread[0] == pytest.approx(0.75e-5, abs=1e-12)
    with pytest.raises(ValueError, match='only 2 poses'):
        calibrate_against_reference(targets[:2], measure)


def test_a_stored_calibration_reads_back_and_a_damaged_one_is_named(tmp_path):
    path = tmp_path / 'tool.json'
    assert read_calibration(path) is None
    write_calibration(path, ToolCorrection(1e-4, 2e-4, 3e-4), poses=6)
    record = read_calibration(path)
    assert record['correction'] == ToolCorrection(1e-4, 2e-4, 3e-4) and record['poses'] == 6
    path.write_text('{"tool_correction": [1e-4, 2e-4]}')
    with pytest.raises(ValueError, match='tool.json is damaged'):
        read_calibration(path)
