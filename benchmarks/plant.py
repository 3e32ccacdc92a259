"""Plant model: evaluation time (one pose, 10 000 poses) and the rigid-model error it gives
on the paper's Table 10 targets, next to the paper's.

    python benchmarks/plant.py [--json]
"""
from __future__ import annotations

import argparse
import json
import math
import timeit

import numpy as np

from flexarm_core.kinematics import ArmGeometry, inverse
from flexarm_core.paper import TABLE_10
from flexarm_core.params import load_config
from flexarm_sim.plant import Plant


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--json', action='store_true', help='print a JSON line last')
    args = parser.parse_args()
    config = load_config('arm.yaml', 'sim.yaml')
    geometry = ArmGeometry.from_dict(config['arm'])
    plant = Plant.from_dict(config['plant'], geometry)
    rng = np.random.default_rng(0)
    batch = rng.uniform(geometry.lower, geometry.upper, (10_000, 4))
    one = batch[0]
    t_one = min(timeit.repeat(lambda: plant.pose(one), number=200, repeat=5)) / 200
    t_batch = min(timeit.repeat(lambda: plant.pose(batch), number=5, repeat=5)) / 5
    horizontal = np.array([0.0, 0.8, 0.0, 0.0])
    tip_5kg = plant.with_payload(5.0).deflection(horizontal) - plant.deflection(horizontal)

    rows = []
    for paper in TABLE_10:
        joints = inverse(geometry, paper.pose)
        err = plant.pose(joints) - paper.pose
        paper_position, paper_angle = paper.rigid_errors
        rows.append({
            'target': paper.name, 'joint2_mm': 1e3 * joints[1],
            'position_error_mm': 1e3 * math.hypot(err[0], err[1]),
            'angle_error_deg': math.degrees(err[2]),
            'paper_position_error_mm': paper_position, 'paper_angle_error_deg': paper_angle})
    figures = {'pose_us': 1e6 * t_one, 'batch_10000_ms': 1e3 * t_batch,
               'tip_deflection_5kg_mm': -1e3 * tip_5kg[1], 'payload_kg': plant.payload,
               'table10': rows}

    print(f'plant: one pose {figures["pose_us"]:.1f} us, 10 000 poses '
          f'{figures["batch_10000_ms"]:.2f} ms (target < 50 ms)')
    print(f'tip deflection from +5 kg at full horizontal extension: '
          f'{figures["tip_deflection_5kg_mm"]:.1f} mm (Table 4 P12/P13: 17.5 mm, design 20 mm)')
    print(f'rigid-model error on Table 10 targets (payload {plant.payload:g} kg):')
    print('target  joint2[mm]  ours: pos[mm] ang[deg]   paper: pos[mm] ang[deg]')
    for r in rows:
        print(f'{r["target"]:>6}  {r["joint2_mm"]:10.0f}  {r["position_error_mm"]:13.1f} '
              f'{r["angle_error_deg"]:8.2f}   {r["paper_position_error_mm"]:14.1f} '
              f'{r["paper_angle_error_deg"]:8.2f}')
    if args.json:
        print(json.dumps(figures))


if __name__ == '__main__':
    main()
