"""Scene geometry: region outlines, deflection arrows and the predicted field behind them."""
import numpy as np
import pytest

from flexarm_core.kinematics import ArmGeometry, forward
from flexarm_core.params import load_config
from flexarm_core.regions import Region
from flexarm_deflection.deflection_field import deflection_field, region_grid
from flexarm_description.scene import deflection_arrows, region_outline, sample_points


@pytest.fixture(scope='module')
def geometry() -> ArmGeometry:
    return ArmGeometry.from_dict(load_config('arm.yaml')['arm'])


REGION = Region('A', np.array([1.40, -0.20, -0.8727]), np.array([1.60, 0.20, 0.0]))


def test_region_outline_is_a_closed_box_in_the_x_z_plane() -> None:
    outline = region_outline(REGION)
    np.testing.assert_allclose(outline[0], outline[-1])
    np.testing.assert_allclose(outline[:, 1], 0.0)
    assert outline[:, 0].min() == 1.40 and outline[:, 2].max() == 0.20


def test_arrows_start_at_the_pose_and_show_the_deflection_scaled() -> None:
    poses = np.array([[1.5, 0.1, -0.3]])
    (start, end), = deflection_arrows(poses, np.array([[0.002, -0.01, 0.001]]), 10.0)
    np.testing.assert_allclose(start, [1.5, 0.0, 0.1])
    np.testing.assert_allclose(end, [1.52, 0.0, 0.0])
    np.testing.assert_allclose(sample_points(poses), [[1.5, 0.0, 0.1]])


def test_field_predicts_at_the_rigid_joints_of_each_reachable_grid_pose(geometry) -> None:
    seen = []

    def predict(joints: np.ndarray) -> np.ndarray:
        seen.append(joints)
        return np.column_stack([joints[:, 0], joints[:, 1], joints[:, 3]])

    near = Region('near', np.array([1.1, -0.3, -1.2]), np.array([1.2, -0.2, -1.0]))
    poses, deflections = deflection_field(geometry, near, predict, count=4)
    assert poses.shape == (16, 3) and deflections.shape == (16, 3)
    np.testing.assert_allclose(poses, region_grid(near, 4))
    np.testing.assert_allclose(forward(geometry, seen[0]), poses, atol=1e-9)
    np.testing.assert_allclose(deflections[:, 0], seen[0][:, 0])
    poses, _ = deflection_field(geometry, REGION, predict, count=4)   # A's far corners
    assert 0 < len(poses) < 16             # the grid poses out of reach are left out
