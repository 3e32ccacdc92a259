"""Compensation compute time per goal, and the paper's alternative side by side.

PREDICTIVE: the fixed point x* = x_d - Delta(IK(x*)) with a predictor (``--kind``, default the
learner's) fitted on 40 learning poses of the goal's region (deflections from the simulator's
plant: this times the computation, not the camera). Alternative (paper section 3-1): invert the
detailed flexible model numerically - least squares on plant.pose(q) = x_d over joints 1, 3, 4
with joint2 from the same rule - which needs the detailed model the paper says is impractical
to build.
Accuracy of both is judged on the plant; times are per goal, on one core.

    python benchmarks/compensation.py [--kind gp] [--targets A1,B4] [--samples 40] [--json]

Smoke run: --kind kinematic --targets A1 --samples 12
"""
from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from flexarm_control.execution.compensator import Compensator
from flexarm_core.kinematics import ArmGeometry, inverse
from flexarm_core.paper import TABLE_10
from flexarm_core.params import load_config
from flexarm_core.regions import configured_regions
from flexarm_deflection.models import make_model
from flexarm_deflection.sampling import sample_poses
from flexarm_sim.plant import Plant


def per_goal(func, repeats: int = 50) -> tuple[float, object]:
    """Best-of-3 mean wall time [s] of ``func()`` and its last result."""
    best, out = math.inf, None
    for _ in range(3):
        start = time.perf_counter()
        for _ in range(repeats):
            out = func()
        best = min(best, (time.perf_counter() - start) / repeats)
    return best, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--kind', help="predictor kind (default: the learner's)")
    parser.add_argument('--targets', default=','.join(t.name for t in TABLE_10),
                        help='comma-separated Table 10 targets')
    parser.add_argument('--samples', type=int, default=40, help='learning poses per region')
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    threadpool_limits(1)
    names = args.targets.split(',')
    if unknown := set(names) - {t.name for t in TABLE_10}:
        parser.error(f'unknown targets {sorted(unknown)}')
    targets = [t for t in TABLE_10 if t.name in names]
    config = load_config('arm.yaml', 'sim.yaml', 'compensator.yaml',
                         node_name='flexarm_compensator')
    geometry = ArmGeometry.from_dict(config['arm'])
    plant = Plant.from_dict(config['plant'], geometry)
    compensator = Compensator(geometry, config['compensation'])
    learner = load_config('learner.yaml', node_name='flexarm_learner')
    regions = configured_regions()
    kind = args.kind or learner['default_kind']
    models = {}
    for name in sorted({t.region for t in targets}):
        _, joints = sample_poses(geometry, regions[name].grown(learner['coverage_margin']),
                                 args.samples, seed=1)
        models[name] = make_model(kind).fit(joints, plant.deflection(joints))

    rows = []
    for t in targets:
        target, model = t.pose, models[t.region]
        t_pred, plan = per_goal(lambda target=target, model=model:
                                  compensator.predictive(target, model.predict))
        err = plant.pose(plan.joints) - target
        extension = inverse(geometry, target)[1]

        def numerical(target: np.ndarray = target, extension: float = extension) -> np.ndarray:
            q0 = inverse(geometry, target)[[0, 2, 3]]
            fit = least_squares(lambda q: plant.pose(np.array([q[0], extension, q[1], q[2]]))
                                - target, q0, xtol=1e-12, ftol=1e-12)
            return np.array([fit.x[0], extension, fit.x[1], fit.x[2]])
        t_num, q_num = per_goal(numerical, repeats=10)
        err_num = plant.pose(q_num) - target
        rows.append({'target': t.name, 'predictive_ms': 1e3 * t_pred,
                     'iterations': plan.iterations,
                     'predictive_error_mm': 1e3 * math.hypot(err[0], err[1]),
                     'predictive_error_deg': abs(math.degrees(err[2])),
                     'numerical_ms': 1e3 * t_num,
                     'numerical_error_mm': 1e3 * math.hypot(err_num[0], err_num[1]),
                     'numerical_error_deg': abs(math.degrees(err_num[2]))})
    print('target  predictive: ms  iter  error mm / deg      numerical inverse: ms  error mm')
    for r in rows:
        print(f'{r["target"]:>6}  {r["predictive_ms"]:14.3f}  {r["iterations"]:4d}  '
              f'{r["predictive_error_mm"]:8.4f} / {r["predictive_error_deg"]:.5f}  '
              f'{r["numerical_ms"]:21.2f}  {r["numerical_error_mm"]:.2e}')
    worst = max(r['predictive_ms'] for r in rows)
    print(f'predictive compensation ({kind}): at most {worst:.3f} ms per goal; '
          f'numerical inverse of the plant: {np.mean([r["numerical_ms"] for r in rows]):.1f} '
          'ms on average, and it needs the detailed model.')
    if args.json:
        print(json.dumps({'kind': kind, 'rows': rows, 'predictive_max_ms': worst}))


if __name__ == '__main__':
    main()
