"""Drift caught and mended: the arm changes after training; is it noticed, and does a refresh of
a few samples bring the open-loop error back?

Offline, in the realistic world of benchmarks/error_budget.py (every error source of
config/sim.yaml on, camera calibrated against the reference; the static simulated arm driven by
the control core's own collection, training, planning and goal execution). Per change scenario,
region (A, B) and training seed:

1. learn: ``--samples`` Sobol learning samples, the learner's default training;
2. ``before``: ``--targets`` PREDICTIVE goals at random targets of the region; their measured
   tips feed the model health (:mod:`flexarm_deflection.model_health`) as in the compensator;
3. the change: ``payload`` a 2 kg tool nobody declared; ``thermal`` the arm 15 K warmer (0.2 mm
   growth at full reach); ``bent_link`` the No.2 arm bent so its end stands 1 mm off its axis
   (config/sim.yaml ``plant.fabrication.offset`` + 1 mm); ``none`` no change (false alarms);
4. ``after``: the same targets again, feeding the health; ``detected_after`` the goals it took
   to mark the region stale;
5. refresh: ``--refresh-samples`` samples at :func:`flexarm_deflection.refresh.refresh_poses`
   (the worst residuals seen, then space-filling), the correction fitted
   (:mod:`flexarm_deflection.drift_correction`); ``refreshed``: the same targets once more.

Errors are the true tip against the target (mm), pooled over regions and seeds (p95, max);
``worst_run_refreshed_p95_mm`` is the worst single run. Target: refreshed ≤ 0.3 mm with ≤ 10
samples.

    python benchmarks/drift.py [--targets 40] [--seeds 3] [--refresh-samples 8] [--kind KIND]
        [--only SCENARIOS] [--json]

``--kind`` trains another predictor kind than the learner's default (a smoke run, a few
seconds, takes a cheap one: ``--seeds 1 --targets 2 --samples 12 --regions A --kind kinematic
--workers 1``).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np
from error_budget import SOURCES, CalibratedMotion, Rig, config, reference_calibration

from flexarm_control.execution.collection import Collector
from flexarm_control.execution.goal_execution import SUCCEEDED, GoalSpec, execute
from flexarm_control.execution.modes import Mode
from flexarm_control.execution.planning import Refusal, plan_goal
from flexarm_core.kinematics import forward, pose_error
from flexarm_core.regions import configured_regions
from flexarm_deflection.cross_validation import Screening
from flexarm_deflection.model_health import HealthSettings, ModelHealth
from flexarm_deflection.predictors import Predictor
from flexarm_deflection.refresh import refresh_poses, refreshed
from flexarm_deflection.sampling import random_targets, sample_poses, travel_order
from flexarm_deflection.selection import fit_robust

SCENARIOS = ('payload', 'thermal', 'bent_link', 'none')
TARGET_SEED = 7100


def change(rig: Rig, scenario: str) -> None:
    """Apply the scenario's change to the simulated arm, untold to the model."""
    arm = rig.arm
    if scenario == 'payload':
        arm.set_payload(arm.plant.payload + 2.0)
    elif scenario == 'thermal':     # 15 K more than the drift so far, at once
        thermal = arm.errors.thermal
        arm.errors.thermal = dataclasses.replace(
            thermal, rise=thermal.temperature(arm.time) + 15.0, duration=1e-9)
    elif scenario == 'bent_link':
        arm.plant = dataclasses.replace(arm.plant, offset_error=arm.plant.offset_error + 1e-3)


def goals(rig: Rig, motion: CalibratedMotion, predictor: Predictor, targets: np.ndarray,
          health: ModelHealth, region: str) -> tuple[list[float], int | None, int]:
    """PREDICTIVE goals at ``targets``: true position errors [mm] of the succeeded ones, the
    goal after which ``region`` was first stale (None: never), and the failed/refused count."""
    errors, stale_at, failed = [], None, 0

    def observe(joints: np.ndarray, measured: np.ndarray) -> None:
        deflection = measured - forward(rig.geometry, joints)
        health.observe(measured, joints, deflection - predictor.predict(joints))

    for k, target in enumerate(targets, start=1):
        planned = plan_goal(rig.compensator, Mode.PREDICTIVE, target, predictor, rig.limits)
        if isinstance(planned, Refusal):
            failed += 1
            continue
        outcome = execute(GoalSpec(target, Mode.PREDICTIVE, 0.0, 0.0, 0), planned.plan, motion,
                          rig.compensator, observe=observe)
        if outcome.status != SUCCEEDED:
            failed += 1
            continue
        errors.append(1e3 * pose_error(target, rig.arm.truth())[0])
        if stale_at is None and region in health.stale_regions():
            stale_at = k
    return errors, stale_at, failed


def run(job: tuple[str, str, int, int, int, int, int, str]) -> dict[str, Any]:
    scenario, region_name, region_index, seed, samples, targets, refresh_count, kind = job
    started = time.perf_counter()
    c = config()
    rig = Rig(c, set(SOURCES) - {'payload'}, 0.0, seed=100 * seed + region_index)
    learner = c['learner']
    regions = configured_regions()
    coverage = np.asarray(learner['coverage_margin'])
    rig.correction = reference_calibration(rig, regions[region_name])['correction']
    motion = CalibratedMotion(rig)
    collector = Collector(motion, rig.geometry, learner['measurement_retries'],
                          clock=lambda: rig.arm.time)
    grown = regions[region_name].grown(coverage)
    _, poses = sample_poses(rig.geometry, grown, samples, 'sobol', seed=100 * seed + region_index)
    poses = poses[travel_order(poses, rig.arm.positions(), rig.geometry.velocity)]
    collected = []
    collector.collect(poses, 0.0, collected.append)
    predictor, _ = fit_robust(
        kind or learner['default_kind'], {}, np.array([s.joints for s in collected]),
        np.array([s.deflection for s in collected]), folds=learner['validation_folds'],
        geometry=rig.geometry, screening=Screening.from_dict(learner['training']))
    health = ModelHealth(HealthSettings.from_dict(c['compensator']['model_health']), regions)
    health.reset('1')
    goal_targets = random_targets(rig.geometry, regions[region_name], targets,
                                  TARGET_SEED + region_index)
    before, false_alarm, failed_before = goals(rig, motion, predictor, goal_targets, health,
                                               region_name)
    change(rig, scenario)
    after, detected, failed_after = goals(rig, motion, predictor, goal_targets, health,
                                          region_name)
    plan = refresh_poses(rig.geometry, grown, health.worst_joints(region_name, refresh_count),
                         refresh_count, seed=seed + 500)
    plan = plan[travel_order(plan, rig.arm.positions(), rig.geometry.velocity)]
    fresh = []
    collector.collect(plan, 0.0, fresh.append)
    mended = refreshed(predictor, rig.geometry, np.array([s.joints for s in fresh]),
                       np.array([s.deflection for s in fresh]), np.zeros(len(fresh)), '2')
    health.reset('2')
    repaired, still_stale, failed_refreshed = goals(rig, motion, mended, goal_targets, health,
                                                    region_name)
    return {'scenario': scenario, 'region': region_name, 'seed': seed,
            'errors': {'before': before, 'after': after, 'refreshed': repaired},
            'false_alarm_at': false_alarm, 'detected_after': detected,
            'stale_after_refresh_at': still_stale, 'refresh_samples': len(fresh),
            'failed': failed_before + failed_after + failed_refreshed,
            'correction': mended.corrections[-1].as_dict(),
            'wall_s': time.perf_counter() - started}


def _p95_max(values: list[float]) -> tuple[float, float]:
    if not values:
        return math.nan, math.nan
    return float(np.percentile(values, 95)), float(np.max(values))


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for phase in ('before', 'after', 'refreshed'):
        p95, worst = _p95_max([e for r in rows for e in r['errors'][phase]])
        out[f'{phase}_p95_mm'], out[f'{phase}_max_mm'] = p95, worst
    out['worst_run_refreshed_p95_mm'] = max(_p95_max(r['errors']['refreshed'])[0] for r in rows)
    out['refresh_samples'] = max(r['refresh_samples'] for r in rows)
    detected = [r['detected_after'] for r in rows]
    out['detected'] = sum(d is not None for d in detected)
    out['runs'] = len(rows)
    out['detected_after_goals'] = max((d for d in detected if d is not None), default=None)
    out['false_alarms'] = sum(r['false_alarm_at'] is not None for r in rows)
    out['stale_after_refresh'] = sum(r['stale_after_refresh_at'] is not None for r in rows)
    out['failed'] = sum(r['failed'] for r in rows)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--targets', type=int, default=40, help='targets per region')
    parser.add_argument('--samples', type=int, default=40, help='learning samples')
    parser.add_argument('--seeds', type=int, default=3)
    parser.add_argument('--refresh-samples', type=int, default=8)
    parser.add_argument('--regions', default='A,B')
    parser.add_argument('--only', help='comma-separated scenarios (default: every one)')
    parser.add_argument('--kind', help="predictor kind (default: the learner's default_kind)")
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    args = parser.parse_args()
    scenarios = args.only.split(',') if args.only else list(SCENARIOS)
    regions = args.regions.split(',')
    jobs = [(scenario, region, i, seed, args.samples, args.targets, args.refresh_samples,
             args.kind or '')
            for scenario in scenarios for i, region in enumerate(regions)
            for seed in range(args.seeds)]
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(run, jobs))
    results = {}
    print('scenario    PRED p95 / max mm: before      after   refreshed | samples  detected '
          '(after goals)  false alarms')
    for scenario in scenarios:
        s = results[scenario] = summary([r for r in rows if r['scenario'] == scenario])
        s['runs_detail'] = [{k: v for k, v in r.items() if k != 'errors'}
                            for r in rows if r['scenario'] == scenario]
        print(f"{scenario:<10} {s['before_p95_mm']:8.3f}/{s['before_max_mm']:.3f} "
              f"{s['after_p95_mm']:8.3f}/{s['after_max_mm']:.3f} "
              f"{s['refreshed_p95_mm']:8.3f}/{s['refreshed_max_mm']:.3f} | "
              f"{s['refresh_samples']:7d} {s['detected']:4d}/{s['runs']} "
              f"({s['detected_after_goals']}) {s['false_alarms']:6d}", flush=True)
    if args.json:
        print(json.dumps({'targets_per_region': args.targets, 'samples': args.samples,
                          'seeds': args.seeds, 'regions': regions, 'scenarios': results}))


if __name__ == '__main__':
    main()
