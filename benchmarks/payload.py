"""Payload-aware prediction: a model trained on samples at 0 and 5 kg, asked at 2.5 kg (never
seen) — or trained at one payload (``--trained 0``) and asked at the others.

Offline, in the realistic world of benchmarks/error_budget.py (every error source on, camera
calibrated against the reference; the learner's collection loop on the static simulated arm).
Per region (A, B) and seed: ``--samples`` learning samples at each ``--trained`` payload (the
arm picks up the next tool between them; other Sobol poses), the payload recorded with each;
the learner's training, with the payload as a model input (``payload_input``) when the samples
hold several payloads, as the learner does. The model is judged against the plant's TRUE
deflection at ``--held-out`` random poses of the region carrying 0, 2.5 and 5 kg, each reached
as every move is (its approach leg takes up the friction the same way), asked at the payload
carried as the compensator asks (:class:`~flexarm_deflection.at_payload.AtPayload`): max and
p95 position error (mm) per payload, pooled over seeds. ``ratio`` = the largest max error at a
payload not trained / the largest at a trained one (target ≤ 1.5), per region and worst over
seeds.

    python benchmarks/payload.py [--samples 20] [--seeds 3] [--kind gp] [--trained 0,5] [--json]
"""
from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np
from error_budget import SOURCES, Rig, collect, config, reference_calibration

from flexarm_core.kinematics import forward
from flexarm_core.regions import configured_regions
from flexarm_deflection.at_payload import AtPayload
from flexarm_deflection.cross_validation import Screening
from flexarm_deflection.sampling import sample_poses
from flexarm_deflection.selection import fit_robust

PAYLOADS = (0.0, 2.5, 5.0)      # [kg] asked


def run(job: tuple[str, int, int, int, int, str, tuple[float, ...]]) -> dict[str, Any]:
    region_name, region_index, seed, samples, held_out, kind, trained = job
    started = time.perf_counter()
    c = config()
    rig = Rig(c, set(SOURCES) - {'payload'}, 0.0, seed=100 * seed + region_index)
    learner = c['learner']
    regions = configured_regions()
    rig.correction = reference_calibration(rig, regions[region_name])['correction']
    collected = []
    for k, kg in enumerate(trained):
        collected += collect(rig, regions[region_name], samples, kg,
                             100 * seed + 10 * region_index + k,
                             np.asarray(learner['coverage_margin']),
                             learner['measurement_retries'])
    predictor, metrics = fit_robust(
        kind, {'payload_input': len(trained) > 1}, np.array([s.joints for s in collected]),
        np.array([s.deflection for s in collected]), np.array([s.payload for s in collected]),
        folds=learner['validation_folds'], geometry=rig.geometry,
        screening=Screening.from_dict(learner['training']))
    _, joints = sample_poses(rig.geometry, regions[region_name], held_out, 'random',
                             seed=9000 + 100 * seed + region_index)
    errors = {}
    for kg in PAYLOADS:
        rig.arm.set_payload(kg)
        truth = []
        for q in joints:       # reached as every move is (the approach leg: the friction)
            rig.motion.move_to(q)
            truth.append(rig.arm.truth() - forward(rig.geometry, rig.arm.positions()))
        miss = AtPayload(predictor, kg).predict(joints) - np.array(truth)
        errors[kg] = (1e3 * np.hypot(miss[:, 0], miss[:, 1])).tolist()
    return {'region': region_name, 'seed': seed, 'samples': len(collected),
            'excluded': len(metrics.excluded_samples), 'errors': errors,
            'ratio': (max(max(errors[kg]) for kg in PAYLOADS if kg not in trained)
                      / max(max(errors[kg]) for kg in trained)),
            'wall_s': time.perf_counter() - started}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--samples', type=int, default=20, help='learning samples per payload')
    parser.add_argument('--held-out', type=int, default=200)
    parser.add_argument('--seeds', type=int, default=3)
    parser.add_argument('--regions', default='A,B')
    parser.add_argument('--kind', help='predictor kind (default: the learner\'s default_kind)')
    parser.add_argument('--trained', default='0,5',
                        help='payloads [kg] learned at, some of 0, 2.5, 5 (not all)')
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    args = parser.parse_args()
    kind = args.kind or config()['learner']['default_kind']
    regions = args.regions.split(',')
    trained = tuple(float(kg) for kg in args.trained.split(','))
    if not set(trained) < set(PAYLOADS):
        parser.error(f'--trained: some of {PAYLOADS} kg, not all')
    jobs = [(region, i, seed, args.samples, args.held_out, kind, trained)
            for i, region in enumerate(regions) for seed in range(args.seeds)]
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(run, jobs))
    out: dict[str, Any] = {'kind': kind, 'trained_kg': list(trained),
                           'samples_per_payload': args.samples,
                           'seeds': args.seeds, 'held_out': args.held_out, 'regions': {}}
    print(f'{kind}, trained at {args.trained} kg: max / p95 position error [mm] at   0 kg'
          '          2.5 kg            5 kg          ratio (worst seed)')
    for region in regions:
        mine = [r for r in rows if r['region'] == region]
        figures = {}
        for kg in PAYLOADS:
            e = np.concatenate([r['errors'][kg] for r in mine])
            figures[f'{kg:g}kg'] = {'max_mm': float(e.max()),
                                    'p95_mm': float(np.percentile(e, 95))}
        ratio = max(r['ratio'] for r in mine)
        out['regions'][region] = {'payloads': figures, 'ratio': ratio,
                                  'ratios': [r['ratio'] for r in mine]}
        print(f'region {region}:' + ''.join(
            f"      {figures[f'{kg:g}kg']['max_mm']:6.3f} / {figures[f'{kg:g}kg']['p95_mm']:.3f}"
            for kg in PAYLOADS) + f'      {ratio:.2f}', flush=True)
    out['ratio'] = max(r['ratio'] for r in out['regions'].values())
    if args.json:
        print(json.dumps(out))


if __name__ == '__main__':
    main()
