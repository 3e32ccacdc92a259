"""The URDF-general learning core on the JAERI arm, beside the graph's planar grey-box: how far
the core is from taking the grey-box's place.

Both learn from the same ``--samples`` poses of a region (the learner's sampling; the
simulated plant's true deflection, as benchmarks/compensation.py does: the model is judged,
not the camera) and predict the tip's position at ``--held-out`` other poses of the region.
The planar grey-box (flexarm_control's, the graph's default structure) predicts the
deflection (dx, dy); the core (flexarm_learning's default kind, on the URDF that ``flexarm
urdf`` writes, in whose frame the arm's plane is x-z) predicts where the tip is, registration
included. Position only: the core does not model orientation yet.

    python benchmarks/core_on_jaeri.py [--regions A,B] [--samples 40] [--held-out 200]
                                       [--seed 0] [--json]

Smoke run: --regions A --samples 12 --held-out 5
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np
from threadpoolctl import threadpool_limits

from flexarm_control.learning.models import make_model
from flexarm_control.learning.sampling import sample_poses
from flexarm_core.kinematics import ArmGeometry, forward
from flexarm_core.params import load_config
from flexarm_core.regions import configured_regions
from flexarm_description.chain import TIP_FRAME
from flexarm_description.urdf_model import robot_description
from flexarm_learning.arm_error import ArmErrorModel
from flexarm_learning.choices import DEFAULT_KIND
from flexarm_learning.measurements import Measurements
from flexarm_learning.urdf_arm import UrdfArm
from flexarm_sim.plant import Plant


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
        truth = forward(geometry, held)[:, :2] + plant.deflection(held)[:, :2]
        start = time.perf_counter()
        planar = make_model('greybox').fit(train, plant.deflection(train))
        planar_s = time.perf_counter() - start
        planar_xy = forward(geometry, held)[:, :2] + planar.predict(held)[:, :2]
        measured = forward(geometry, train)[:, :2] + plant.deflection(train)[:, :2]
        points = np.column_stack([measured[:, 0], np.zeros(len(train)), measured[:, 1]])
        start = time.perf_counter()
        core = ArmErrorModel(arm, DEFAULT_KIND).fit(Measurements(
            train, points, np.zeros(len(train)), np.arange(len(train)).astype(str)))
        core_s = time.perf_counter() - start
        core_points, radius = core.predict(held)
        core_error = np.linalg.norm(core_points[:, [0, 2]] - truth, axis=1)
        planar_error = np.linalg.norm(planar_xy - truth, axis=1)
        rigid_error = np.linalg.norm(forward(geometry, held)[:, :2] - truth, axis=1)
        result['regions'][name] = {
            'rigid_mean_mm': 1e3 * rigid_error.mean(),
            'planar_greybox_mean_mm': 1e3 * planar_error.mean(),
            'planar_greybox_max_mm': 1e3 * planar_error.max(),
            'core_mean_mm': 1e3 * core_error.mean(), 'core_max_mm': 1e3 * core_error.max(),
            'core_out_of_plane_max_mm': 1e3 * float(np.abs(core_points[:, 1]).max()),
            'core_coverage': float(np.mean(core_error <= radius)),
            'planar_fit_s': planar_s, 'core_fit_s': core_s}
        r = result['regions'][name]
        print(f"region {name}: rigid {r['rigid_mean_mm']:.3f} mm, planar grey-box "
              f"{r['planar_greybox_mean_mm']:.4f} mm (max {r['planar_greybox_max_mm']:.4f}), "
              f"URDF core {r['core_mean_mm']:.4f} mm (max {r['core_max_mm']:.4f}, coverage "
              f"{r['core_coverage']:.3f})")
    print(json.dumps(result) if args.json else json.dumps(result, indent=1))


if __name__ == '__main__':
    main()
