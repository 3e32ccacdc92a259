"""The learning core on the JAERI arm, as the graph runs it: the grey-box (the robot
description's elastostatic model through flexarm_learning, all its elastic terms, the
camera's registration held) with and without its residual GP.

Both learn from the same ``--samples`` poses of a region (the learner's sampling; the
simulated plant's true deflection, as benchmarks/compensation.py does: the model is judged,
not the camera) and predict the tip's pose at ``--held-out`` other poses of the region, the
simulated plant's truth against it. ``predict_ms``: the fastest of the grey-box's predictions
of four held-out rows (what a compensation step asks for; a goal makes four such calls or
fewer).

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

from flexarm_core.kinematics import ArmGeometry, forward, wrap_angle
from flexarm_core.params import load_config
from flexarm_core.regions import configured_regions
from flexarm_deflection.models import make_model
from flexarm_deflection.sampling import sample_poses
from flexarm_sim.plant import Plant

PLAN_ROWS = 4      # rows a compensation step predicts at once: the point and three probes


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
    learner = load_config('learner.yaml', node_name='flexarm_learner')
    regions = configured_regions()
    result: dict = {'samples': args.samples, 'held_out': args.held_out, 'regions': {}}
    for name in args.regions.split(','):
        region = regions[name].grown(learner['coverage_margin'])
        _, train = sample_poses(geometry, region, args.samples, seed=2 * args.seed + 1)
        _, held = sample_poses(geometry, regions[name], args.held_out, strategy='random',
                               seed=2 * args.seed + 2)
        truth = plant.pose(held)
        rigid_error = np.linalg.norm(forward(geometry, held)[:, :2] - truth[:, :2], axis=1)
        figures = {'rigid_mean_mm': 1e3 * rigid_error.mean()}
        for label, residual in (('structure', 'none'), ('greybox', 'gp')):
            start = time.perf_counter()
            model = make_model('greybox', {'residual': residual}).fit(
                train, plant.deflection(train))
            fit_s = time.perf_counter() - start
            pose = forward(geometry, held) + model.predict(held)
            error = np.linalg.norm(pose[:, :2] - truth[:, :2], axis=1)
            figures.update({
                f'{label}_mean_mm': 1e3 * error.mean(), f'{label}_max_mm': 1e3 * error.max(),
                f'{label}_max_deg': float(np.degrees(
                    np.abs(wrap_angle(pose[:, 2] - truth[:, 2])).max())),
                f'{label}_fit_s': fit_s})
        figures['predict_ms'] = 1e3 * min(_timed(model.predict, held[k:k + PLAN_ROWS])
                                          for k in range(0, len(held) - PLAN_ROWS + 1,
                                                         PLAN_ROWS))
        result['regions'][name] = figures
        print(f"region {name}: rigid {figures['rigid_mean_mm']:.3f} mm, structure "
              f"{figures['structure_mean_mm']:.4f} mm (max {figures['structure_max_mm']:.4f}),"
              f" grey-box {figures['greybox_mean_mm']:.4f} mm (max "
              f"{figures['greybox_max_mm']:.4f}, {figures['greybox_max_deg']:.4f}°), four "
              f"rows predicted in {figures['predict_ms']:.2f} ms")
    print(json.dumps(result) if args.json else json.dumps(result, indent=1))


def _timed(func, *args) -> float:
    """Wall time [s] of one call."""
    start = time.perf_counter()
    func(*args)
    return time.perf_counter() - start


if __name__ == '__main__':
    main()
