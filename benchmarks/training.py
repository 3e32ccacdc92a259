"""Deflection predictors: training time for 50 samples per kind with its default settings (a
fit; the learner also cross-validates its choices, up to ~10 s on one core is acceptable),
5-fold cross-validated training time, prediction time per single query and per batch of
1000, and the held-out error on a synthetic sag-like deflection (~20 mm, ~1.5°).

Usage: .venv/bin/python benchmarks/training.py [--samples 50] [--repeats 3] [--kinds mlp,gp]
[--json]; smoke run: --samples 12 --repeats 1 --kinds kinematic,gp
"""
from __future__ import annotations

import argparse
import json
import statistics
import time
from collections.abc import Callable

import numpy as np

from flexarm_deflection.models import KINDS, make_model
from flexarm_deflection.training import validate

LOWER = np.array([-0.5, 0.3, -1.5, -1.0])   # working region [rad, m, rad, rad]
UPPER = np.array([0.5, 0.8, 0.5, 1.0])


def sag(joints: np.ndarray) -> np.ndarray:
    """Synthetic deflection (dx, dy [m], dφ [rad]) smooth in the joint positions."""
    t1, t2, t3, t4 = joints.T
    a3, a4 = t1 + t3, t1 + t3 + t4
    s = t2 / 0.6
    return np.column_stack([0.006 * np.sin(t1) * np.cos(a3) * s,
                            -0.012 * (0.5 + 0.5 * np.cos(t1) ** 2) * s ** 2 - 0.003 * np.cos(a4),
                            -0.02 * np.cos(a3) * s - 0.01 * np.sin(a4)])


def seconds(run: Callable[[], object], repeats: int) -> float:
    """Median wall time of ``run`` over ``repeats`` calls."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--samples', type=int, default=50)
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--kinds', default=','.join(KINDS), help='comma-separated kinds')
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    joints = LOWER + (UPPER - LOWER) * rng.random((args.samples, 4))
    deflections = sag(joints)
    queries = LOWER + (UPPER - LOWER) * rng.random((1000, 4))
    results = {'samples': args.samples}
    for kind in args.kinds.split(','):
        start = time.perf_counter()
        model = make_model(kind).fit(joints, deflections)   # first fit: includes warm-up
        first = time.perf_counter() - start
        fit = seconds(lambda kind=kind: make_model(kind).fit(joints, deflections),
                      args.repeats)
        cv = seconds(lambda kind=kind: validate(kind, None, joints, deflections, folds=5), 1)
        single = seconds(lambda model=model: [model.predict(q) for q in queries[:200]],
                         args.repeats) / 200
        batch = seconds(lambda model=model: model.predict(queries), args.repeats)
        errors = np.abs(model.predict(queries) - sag(queries))
        results[kind] = {
            'fit_s': fit, 'first_fit_s': first, 'cross_validation_5fold_s': cv,
            'predict_single_us': single * 1e6, 'predict_batch1000_ms': batch * 1e3,
            'held_out_max_error': errors.max(axis=0).tolist(),
            'held_out_mean_error': errors.mean(axis=0).tolist()}
        worst, mean = errors.max(axis=0), errors.mean(axis=0)
        print(f'{kind}: fit {fit:.3f} s (first {first:.3f} s), 5-fold CV '
              f'{cv:.2f} s, predict {single * 1e6:.0f} µs/query, {batch * 1e3:.2f} ms/1000; '
              f'held-out max {worst[0] * 1e3:.2f} / {worst[1] * 1e3:.2f} mm / '
              f'{np.degrees(worst[2]):.3f}°, mean {mean[0] * 1e3:.3f} / {mean[1] * 1e3:.3f} mm'
              f' / {np.degrees(mean[2]):.4f}°')
    if args.json:
        print(json.dumps(results))


if __name__ == '__main__':
    main()
