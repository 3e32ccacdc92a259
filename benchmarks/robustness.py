"""Compensation that holds across a whole working region, whatever the training samples were.

Offline, against the simulated arm's truth. For each region (A, B) and each training seed:
``--samples`` learning samples as the learner measures them (its poses: the region grown by
its coverage margin; the tip camera's image of the true arm through the vision estimator),
the learner's default training (kind, folds and screening of config/learner.yaml), then
``--targets`` targets uniform in the region's box (the rigid-reachable ones), PREDICTIVE
planned as the compensator plans it (solver and learned-data limits of
config/compensator.yaml) and judged on the plant. Then again with one sample's deflection
moved 10 mm in a random direction (the outlier run).

A rigid-reachable target near the edge of the workspace can be out of the true arm's reach:
the arm sags ~20 mm there, and the rigid pose that would lift it back lies beyond the longest
extension with the elbow bent the configured minimum. Such targets (the compensator refuses
them, as it must) are counted as ``out_of_reach``, found by planning with the plant's true
deflection; ``refused`` counts refusals of targets the true arm can reach.

    python benchmarks/robustness.py [--seeds 5] [--targets 200] [--kind gp] [--json]

JSON: ``refused``, ``max_mm``, ``p95_mm``, ``max_deg`` (and ``out_of_reach``, the largest
``max_data_distance`` and ``max_std_mm`` of executed plans) at the top level are the worst
over every seed and region of the clean runs; ``outlier`` holds the same for the outlier runs
(plus ``detected``: runs whose bad sample was excluded); ``runs`` every run's figures.
"""
from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from flexarm_cli.study import World
from flexarm_control.execution.compensator import CompensationError, Compensator
from flexarm_control.execution.planning import DataLimits, Refusal, plan_goal
from flexarm_core.kinematics import pose_error
from flexarm_core.params import load_config
from flexarm_deflection.cross_validation import Screening
from flexarm_deflection.sampling import random_targets
from flexarm_deflection.selection import fit_robust

OUTLIER = 0.010        # [m] the bad sample's error
TARGET_SEED = 5000     # targets of region R, seed k: TARGET_SEED + k


def corrupt(deflections: np.ndarray, seed: int) -> tuple[np.ndarray, int]:
    """A copy with one sample (chosen by ``seed``) moved ``OUTLIER`` in x, y; its index."""
    rng = np.random.default_rng(seed)
    index, angle = int(rng.integers(len(deflections))), rng.uniform(0, 2 * math.pi)
    bad = deflections.copy()
    bad[index, :2] += OUTLIER * np.array([math.cos(angle), math.sin(angle)])
    return bad, index


def run(world: World, compensator: Compensator, limits: DataLimits, learner: dict,
        region: str, seed: int, samples: int, targets: np.ndarray, kind: str,
        outlier: bool) -> dict:
    """One training set and its evaluation on ``targets``."""
    joints, deflections = world.measured(region, samples, seed)
    bad_index = None
    if outlier:
        deflections, bad_index = corrupt(deflections, seed)
    start = time.perf_counter()
    predictor, metrics = fit_robust(
        kind, {'seed': seed} if 'seed' in _defaults(kind) else {}, joints, deflections,
        folds=learner['validation_folds'], geometry=world.geometry,
        screening=Screening.from_dict(learner['training']))
    train_s = time.perf_counter() - start
    errors, angles, distances, stds, reasons, out_of_reach = [], [], [], [], [], 0
    for target in targets:
        planned = plan_goal(compensator, 'predictive', target, predictor, limits)
        if isinstance(planned, Refusal):
            try:
                compensator.predictive(target, world.plant.deflection)
            except CompensationError:
                out_of_reach += 1
                continue
            reasons.append(planned.reason)
            continue
        position, angle = pose_error(target, world.plant.pose(planned.plan.joints))
        errors.append(1e3 * position)
        angles.append(math.degrees(angle))
        distances.append(planned.data_distance)
        stds.append(1e3 * planned.prediction_std)
    errors = np.array(errors)
    return {'region': region, 'seed': seed, 'outlier': outlier, 'train_s': train_s,
            'selected': metrics.selected_settings, 'excluded': list(metrics.excluded_samples),
            'detected': None if bad_index is None else bad_index in metrics.excluded_samples,
            'targets': len(targets), 'out_of_reach': out_of_reach, 'refused': len(reasons),
            'reasons': reasons[:3],
            'max_mm': float(errors.max(initial=0)),
            'p95_mm': float(np.percentile(errors, 95)) if len(errors) else math.nan,
            'mean_mm': float(errors.mean()) if len(errors) else math.nan,
            'max_deg': float(max(angles, default=0.0)),
            'max_data_distance': float(max(distances, default=0.0)),
            'max_std_mm': float(max(stds, default=0.0))}


def _defaults(kind: str) -> dict:
    from flexarm_deflection.models import make_model
    return make_model(kind).defaults


def worst(rows: list[dict]) -> dict:
    return {key: max(r[key] for r in rows)
            for key in ('refused', 'max_mm', 'p95_mm', 'max_deg', 'max_data_distance',
                        'max_std_mm', 'train_s', 'out_of_reach')}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seeds', type=int, default=5, help='training seeds per region')
    parser.add_argument('--samples', type=int, default=40)
    parser.add_argument('--targets', type=int, default=200, help='targets per region')
    parser.add_argument('--regions', default='A,B')
    parser.add_argument('--kind', help="predictor kind (default: the learner's)")
    parser.add_argument('--method', help="compensation method (default: the compensator's)")
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    args = parser.parse_args()
    learner = load_config('learner.yaml', node_name='flexarm_learner')
    config = load_config('compensator.yaml', node_name='flexarm_compensator')
    settings = config['compensation']
    limits = DataLimits(config['max_data_distance'], config['max_prediction_std'])
    if args.method:
        settings = {**settings, 'method': args.method}
    world = World()
    compensator = Compensator(world.geometry, settings)
    kind = args.kind or learner['default_kind']
    rows = []
    print('region seed outlier  train s  out of reach  refused  max mm   p95 mm  mean mm  '
          'max deg  data dist  std mm  excluded  chosen')
    for outlier in (False, True):
        for region in args.regions.split(','):
            for seed in range(args.seeds):
                targets = random_targets(world.geometry, world.regions[region], args.targets,
                                         TARGET_SEED + seed)
                r = run(world, compensator, limits, learner, region, seed, args.samples,
                        targets, kind, outlier)
                rows.append(r)
                print(f"{region:>6} {seed:4d} {str(outlier):>7} {r['train_s']:8.2f} "
                      f"{r['out_of_reach']:13d} {r['refused']:8d} {r['max_mm']:7.3f} "
                      f"{r['p95_mm']:8.3f} {r['mean_mm']:8.3f} {r['max_deg']:8.4f} "
                      f"{r['max_data_distance']:10.2f} {r['max_std_mm']:7.3f}  {r['excluded']} "
                      f"{r['selected']}", flush=True)
                for reason in r['reasons']:
                    print(f'        refused: {reason}')
    clean = worst([r for r in rows if not r['outlier']])
    bad_rows = [r for r in rows if r['outlier']]
    bad = {**worst(bad_rows), 'detected': sum(bool(r['detected']) for r in bad_rows),
           'runs': len(bad_rows)}
    print(f"kind {kind}, method {settings.get('method', 'newton')}: worst of "
          f"{len(rows) // 2} clean runs: refused {clean['refused']}, max {clean['max_mm']:.3f}"
          f" mm, p95 {clean['p95_mm']:.3f} mm, max {clean['max_deg']:.4f} deg; with a 10 mm "
          f"outlier: refused {bad['refused']}, max {bad['max_mm']:.3f} mm, p95 "
          f"{bad['p95_mm']:.3f} mm, max {bad['max_deg']:.4f} deg, outlier excluded in "
          f"{bad['detected']}/{bad['runs']}")
    if args.json:
        print(json.dumps({**clean, 'outlier': bad, 'kind': kind,
                          'method': settings.get('method', 'newton'), 'runs': rows}))


if __name__ == '__main__':
    main()
