"""The URDF-general learning core on the JAERI arm, beside the graph's planar grey-box: how far
the core is from taking the grey-box's place.

Both learn from the same ``--samples`` poses of a region (the learner's sampling; the
simulated plant's true tip pose, as benchmarks/compensation.py does: the model is judged, not
the camera) and predict the tip's pose at ``--held-out`` other poses of the region. The planar
grey-box (flexarm_control's, the graph's default structure) predicts the deflection (dx, dy,
dφ); the core (flexarm_learning's elastostatic model with all its elastic terms, on the URDF
that ``flexarm urdf`` writes, in whose frame the arm's plane is x-z and φ a turn about −y)
predicts the tip's position and rotation, as the graph would use it: the camera's
registration known (held), the tip's position and angle measured. ``core_predict_ms`` is
the fastest of the predictions of five held-out rows, what a compensation step asks for.

    python benchmarks/core_on_jaeri.py [--regions A,B] [--samples 40] [--held-out 200]
                                       [--seed 0] [--json]

Smoke run: --regions A --samples 12 --held-out 5
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np
import pinocchio as pin
from threadpoolctl import threadpool_limits

from flexarm_control.learning.models import make_model
from flexarm_control.learning.sampling import sample_poses
from flexarm_core.kinematics import ArmGeometry, forward, wrap_angle
from flexarm_core.params import load_config
from flexarm_core.regions import configured_regions
from flexarm_description.chain import TIP_FRAME
from flexarm_description.urdf_model import robot_description
from flexarm_learning.elastostatic import TERMS, ElastostaticModel
from flexarm_learning.urdf_arm import UrdfArm
from flexarm_sim.plant import Plant

PLAN_ROWS = 5      # rows a compensation step predicts at once (the point and its Jacobian's)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--regions', default='A,B')
    parser.add_argument('--samples', type=int, default=40, help='learning poses per region')
    parser.add_argument('--held-out', type=int, default=200, help='judged poses per region')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    threadpool_limits(1)
    config = load_config('arm.yaml', 'sim.yaml')
    geometry = ArmGeometry.from_dict(config['arm'])
    plant = Plant.from_dict(config['plant'], geometry)
    arm = UrdfArm.from_xml(robot_description(geometry, config['arm']['inertia'], hardware=''),
                           TIP_FRAME)
    learner = load_config('learner.yaml', node_name='flexarm_learner')
    regions = configured_regions()
    result: dict = {'samples': args.samples, 'held_out': args.held_out, 'regions': {}}
    for name in args.regions.split(','):
        region = regions[name].grown(learner['coverage_margin'])
        _, train = sample_poses(geometry, region, args.samples, seed=2 * args.seed + 1)
        _, held = sample_poses(geometry, regions[name], args.held_out, strategy='random',
                               seed=2 * args.seed + 2)
        truth = plant.pose(held)
        start = time.perf_counter()
        planar = make_model('greybox').fit(train, plant.deflection(train))
        planar_s = time.perf_counter() - start
        planar_pose = forward(geometry, held) + planar.predict(held)
        points, rotations = _in_urdf(plant.pose(train))
        start = time.perf_counter()
        core = ElastostaticModel(arm, registration=False, terms=TERMS).fit(
            train, points, rotations=rotations)
        core_s = time.perf_counter() - start
        core_points, core_rotations = core.predict_pose(held)
        predict_ms = 1e3 * min(_timed(core.predict_pose, held[k:k + PLAN_ROWS])
                               for k in range(0, len(held) - PLAN_ROWS + 1, PLAN_ROWS))
        core_phi = np.array([-pin.log3(r)[1] for r in core_rotations])
        core_error = np.linalg.norm(core_points[:, [0, 2]] - truth[:, :2], axis=1)
        planar_error = np.linalg.norm(planar_pose[:, :2] - truth[:, :2], axis=1)
        rigid_error = np.linalg.norm(forward(geometry, held)[:, :2] - truth[:, :2], axis=1)
        result['regions'][name] = {
            'rigid_mean_mm': 1e3 * rigid_error.mean(),
            'planar_greybox_mean_mm': 1e3 * planar_error.mean(),
            'planar_greybox_max_mm': 1e3 * planar_error.max(),
            'planar_greybox_max_deg': float(np.degrees(
                np.abs(wrap_angle(planar_pose[:, 2] - truth[:, 2])).max())),
            'core_mean_mm': 1e3 * core_error.mean(), 'core_max_mm': 1e3 * core_error.max(),
            'core_max_deg': float(np.degrees(np.abs(wrap_angle(core_phi - truth[:, 2])).max())),
            'core_out_of_plane_max_mm': 1e3 * float(np.abs(core_points[:, 1]).max()),
            'planar_fit_s': planar_s, 'core_fit_s': core_s, 'core_predict_ms': predict_ms}
        r = result['regions'][name]
        print(f"region {name}: rigid {r['rigid_mean_mm']:.3f} mm, planar grey-box "
              f"{r['planar_greybox_mean_mm']:.4f} mm (max {r['planar_greybox_max_mm']:.4f}), "
              f"URDF core {r['core_mean_mm']:.4f} mm (max {r['core_max_mm']:.4f}, "
              f"{r['core_max_deg']:.4f}°), a plan's prediction {predict_ms:.2f} ms")
    print(json.dumps(result) if args.json else json.dumps(result, indent=1))


def _timed(func, *args) -> float:
    """Wall time [s] of one call."""
    start = time.perf_counter()
    func(*args)
    return time.perf_counter() - start


def _in_urdf(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Planar tip poses (N, 3) [m, m, rad] as the URDF's points (x, 0, y) and rotations (a
    turn φ about −y)."""
    points = np.column_stack([poses[:, 0], np.zeros(len(poses)), poses[:, 1]])
    return points, np.array([pin.exp3(np.array([0.0, -phi, 0.0])) for phi in poses[:, 2]])


if __name__ == '__main__':
    main()
