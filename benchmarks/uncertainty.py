"""Does every plan's stated 95 % error bound hold — also where the model was not taught?

Offline, in the realistic world of benchmarks/error_budget.py (every error source on, the
camera calibrated against the reference; the learner's collection loop and training, the
compensator's planning with config/compensator.yaml's ``error_bound``). Per scenario, region
(A, B) and seed: ``--samples`` learning samples at the payload trained at, the learner's
training (``--kind``, default its default kind), then ``--targets`` targets uniform in the
region, each planned PREDICTIVE at the payload the arm carries (as the compensator asks:
:class:`~flexarm_deflection.at_payload.AtPayload`; refused as the compensator refuses,
e.g. beyond the learned data: ``refused``) and moved to; the true tip (the
simulator's) against the target is the goal's error, the plan's ``bound`` what it stated
beforehand. Scenarios (the simulated arm's truth; the model knows the nominal description):

- ``nominal``: the simulator's arm as configured (its masses 4.3 % over the nominal ones).
- ``masses_off``: the No.2 arm 15 % heavier with a 0.6 kg cable harness, the end effector 10 %
  heavier with its CoM 30 mm further out; ``masses_light``: every part 8 % lighter, the end
  effector's CoM 20 mm nearer.
- ``payload_5kg`` / ``payload_5kg_masses_off``: trained at 0 kg, 5 kg carried and declared.
- ``payload_5kg_refreshed``: as ``payload_5kg_masses_off``, with ``--samples`` / 4 samples
  more collected at 5 kg (what a refresh brings) and the model trained on both payloads.
- ``samples_10``: 10 learning samples; ``kind_<k>``: another predictor kind (nominal).
- ``drift``: 2 kg carried and not declared (no model can know it; the model health does),
  reported apart from the pooled figures: the bound as trained, nothing measured.
- ``drift_refresh``: the same change, then as the compensator runs (:mod:`flexarm_control.
  execution.bound_check`): ``--drift-goals`` PREDICTIVE goals one after the other, each
  measured by the camera and held against its stated bound, which the online bound widens from
  each one (``under_drift``); then an ``REFRESH_SAMPLES``-sample refresh where the model
  health saw the worst residuals (:mod:`flexarm_deflection.refresh`: its bound
  recalibrated) and as many goals more on the refreshed model (``after_refresh``).
- ``auto_drift``: the same change, ``--drift-goals`` AUTO goals at ``AUTO_TOLERANCE`` one after
  the other with the online bound (AUTO corrects when it measures its tolerance missed).

Keys: ``coverage`` (share of goals whose true position error is within the stated position
bound, scenarios pooled, drift apart) ≥ 0.95; ``coverage_min`` (worst scenario) ≥ 0.90;
``sharpness`` (median bound / median true error, nominal) ≤ 3, beside ``sharpness_floor``: the
same of a bound that knows the simulated servos' true repeatability (config/sim.yaml) and
nothing else — the exact 95 % radius of the tip error they cause, which the errors that
move the tip mostly across the arm make near one-dimensional (95 % point / median 1.96 / 0.67
= 2.9 for a one-dimensional normal error); ``unsafe_moves`` (goals that a
0.5 mm tolerance would have let move — bound within it — and that missed it) 0; ``mlp_fit_s``
(the MLP ensemble on 40 samples, a learner's second and later fits) ≤ 2, beside
``mlp_first_fit_s`` (its first: torch imported and its optimisers' first use, once per
learner worker). Under drift (reported apart): ``coverage_under_drift`` ≥ 0.9 (the first
goal after the change may miss), ``coverage_after_refresh`` ≥ 0.9 and
``sharpness_after_refresh`` ≤ 3, ``auto_under_drift_unsafe`` = 0 (AUTO goals neither refused
nor within their tolerance by the truth). At the untrained payload (``payload_5kg``):
``sharpness_payload`` ≤ 3 with ``coverage_payload`` ≥ 0.95. ``scenarios``: per scenario goals,
coverage, median bound and error, the largest error and what it stated there, ``refused``.

    python benchmarks/uncertainty.py [--targets 15] [--samples 40] [--seeds 1] [--json]
    python benchmarks/uncertainty.py --smoke --json      (~10 s: three scenarios, small)
"""
from __future__ import annotations

import argparse
import copy
import json
import math
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np
from error_budget import SOURCES, CalibratedMotion, Rig, collect, config, reference_calibration

from flexarm_control.execution.bound_check import OnlineBound, OnlineSettings
from flexarm_control.execution.collection import Collector
from flexarm_control.execution.compensator import CompensationError
from flexarm_control.execution.goal_execution import GoalSpec, execute
from flexarm_control.execution.modes import Mode
from flexarm_control.execution.plan_bound import SiteErrors
from flexarm_control.execution.planning import Planned, plan_goal
from flexarm_core.kinematics import forward, pose_error
from flexarm_core.regions import configured_regions
from flexarm_deflection.at_payload import AtPayload
from flexarm_deflection.cross_validation import Screening
from flexarm_deflection.model_health import HealthSettings, ModelHealth
from flexarm_deflection.predictors import make_predictor
from flexarm_deflection.refresh import refresh_poses, refreshed
from flexarm_deflection.sampling import random_targets, travel_order
from flexarm_deflection.selection import fit_robust

TOLERANCE = 5e-4           # [m] the unsafe-move check's tolerance
TARGET_SEED = 7100
DRIFT_GOALS = 20           # goals after the change, per phase, region and seed
REFRESH_SAMPLES = 8
AUTO_TOLERANCE = (2e-4, math.radians(0.05))    # [m, rad] the AUTO goals' under drift
MASSES_OFF = {'scale': {'second_arm': 1.15, 'end_effector': 1.10},
              'add': {'second_arm': 0.6}, 'com': 0.03}
MASSES_LIGHT = {'scale': dict.fromkeys(('second_axis', 'second_arm', 'third_axis', 'third_arm',
                                        'fourth_axis', 'fourth_arm', 'end_effector'), 0.92),
                'add': {}, 'com': -0.02}
# name: what differs from the nominal scenario (plant masses, samples, carried and declared
# payload [kg], a refresh at it, predictor kind)
SCENARIOS: dict[str, dict[str, Any]] = {
    'nominal': {},
    'masses_off': {'masses': MASSES_OFF},
    'masses_light': {'masses': MASSES_LIGHT},
    'payload_5kg': {'carried': 5.0},
    'payload_5kg_masses_off': {'masses': MASSES_OFF, 'carried': 5.0},
    'payload_5kg_refreshed': {'masses': MASSES_OFF, 'carried': 5.0, 'refreshed': True},
    'samples_10': {'samples': 10},
    'kind_gp': {'kind': 'gp'},
    'kind_greybox': {'kind': 'greybox'},
    'kind_mlp': {'kind': 'mlp'},
    'drift': {'carried': 2.0, 'declared': False},
    'drift_refresh': {'carried': 2.0, 'declared': False, 'sequence': 'refresh'},
    'auto_drift': {'carried': 2.0, 'declared': False, 'sequence': 'auto'},
}
DRIFTING = ('drift', 'drift_refresh', 'auto_drift')      # apart from the pooled figures
SMOKE = ('nominal', 'payload_5kg_masses_off', 'drift_refresh')


def plant_config(c: dict[str, Any], masses: dict[str, Any] | None) -> dict[str, Any]:
    """The configuration with the simulated arm's masses changed by ``masses``."""
    c = copy.deepcopy(c)
    if masses:
        plant = c['plant']
        for part, factor in masses['scale'].items():
            plant['masses'][part] *= factor
        for part, kg in masses['add'].items():
            plant['masses'][part] += kg
        plant['end_effector_com'] += masses['com']
    return c


def run(job: tuple[str, str, int, int, int, int, str, int]) -> dict[str, Any]:
    """One scenario in one region with one seed: learn, then every target PREDICTIVE."""
    name, region_name, region_index, seed, samples, targets, kind, drift_goals = job
    scenario = SCENARIOS[name]
    started = time.perf_counter()
    c = plant_config(config(), scenario.get('masses'))
    rig = Rig(c, set(SOURCES) - {'payload'}, 0.0, seed=100 * seed + region_index)
    rig.arm.set_payload(0.0)
    learner = c['learner']
    region = configured_regions()[region_name]
    rig.correction = reference_calibration(rig, region)['correction']
    coverage = np.asarray(learner['coverage_margin'])
    retries = learner['measurement_retries']
    count = scenario.get('samples', samples)
    collected = collect(rig, region, count, 0.0, 100 * seed + region_index, coverage, retries)
    carried = scenario.get('carried', 0.0)
    if scenario.get('refreshed'):
        collected += collect(rig, region, max(4, samples // 4), carried,
                             100 * seed + region_index + 50, coverage, retries)
    payloads = np.array([s.payload for s in collected])
    predictor, _ = fit_robust(
        scenario.get('kind', kind or learner['default_kind']),
        {'payload_input': np.ptp(payloads) > 0} if scenario.get('refreshed') else {},
        np.array([s.joints for s in collected]), np.array([s.deflection for s in collected]),
        payloads, folds=learner['validation_folds'], geometry=rig.geometry,
        screening=Screening.from_dict(learner['training']))
    rig.arm.set_payload(carried)
    declared = carried if scenario.get('declared', True) else 0.0
    model = AtPayload(predictor, declared)
    site = SiteErrors.from_dict(c['compensator']['error_bound'])
    if 'sequence' in scenario:
        phases = in_sequence(rig, c, region, region_name, seed + region_index, model,
                             sorted(set(payloads)), site, scenario['sequence'], drift_goals)
        return {'name': name, 'region': region_name, 'seed': seed, 'samples': len(collected),
                'phases': phases, 'goals': [], 'refused': 0, 'out_of_reach': 0,
                'wall_s': time.perf_counter() - started}
    servos = SiteErrors(np.asarray(c['error_sources']['repeatability']['sigma']), (0.0, 0.0),
                        (0.0, 0.0))      # the simulated servos' true errors, nothing else
    goals, refused, out_of_reach = [], 0, 0
    for target in random_targets(rig.geometry, region, targets, TARGET_SEED + 10 * seed
                                 + region_index):
        try:        # can the true arm reach it? (robustness.py: the sag near the edge)
            rig.compensator.predictive(target, rig.arm.plant.deflection)
        except CompensationError:
            out_of_reach += 1
            continue
        planned = plan_goal(rig.compensator, Mode.PREDICTIVE, target, model, rig.limits,
                            trained_payloads=sorted(set(payloads)), site=site)
        if not isinstance(planned, Planned):
            refused += 1
            continue
        rig.motion.move_to(planned.plan.joints)
        position, angle = pose_error(target, rig.arm.truth())
        goals.append((position, angle, *planned.bound, servos.at(rig.geometry,
                                                                 planned.plan.joints)[0]))
    return {'name': name, 'region': region_name, 'seed': seed, 'samples': len(collected),
            'goals': goals, 'refused': refused, 'out_of_reach': out_of_reach,
            'wall_s': time.perf_counter() - started}


def in_sequence(rig: Rig, c: dict[str, Any], region: Any, region_name: str, seed: int,
                model: AtPayload, payloads: list[float], site: SiteErrors, kind: str,
                count: int) -> dict[str, list[tuple[float, ...]]]:
    """Goals one after the other as the compensator runs them after the change: each planned
    with the online bound's factor, moved, measured, held against its bound (which the online
    bound then learns from) and filed in the model health; per phase, every goal's (true
    position error, true angle error, stated position bound, stated angle bound, refused)."""
    motion = CalibratedMotion(rig)
    online = OnlineBound(OnlineSettings.from_dict(c['compensator']['online_bound']))
    health = ModelHealth(HealthSettings.from_dict(c['compensator']['model_health']),
                         {region_name: region})
    tolerance = AUTO_TOLERANCE if kind == 'auto' else (0.0, 0.0)
    mode = Mode.AUTO if kind == 'auto' else Mode.PREDICTIVE

    def goals(model: AtPayload, version: str, phase_seed: int) -> list[tuple[float, ...]]:
        online.reset(version)
        health.reset(version)

        def observe(joints: np.ndarray, measured: np.ndarray) -> None:
            health.observe(measured, joints, measured - forward(rig.geometry, joints)
                           - model.predict(joints))

        rows = []
        for target in random_targets(rig.geometry, region, count, phase_seed):
            planned = plan_goal(rig.compensator, mode, target, model, rig.limits,
                                trained_payloads=payloads, site=site, tolerance=tolerance,
                                inflation=online.inflation)
            if not isinstance(planned, Planned):
                rows.append((math.nan, math.nan, math.nan, math.nan, 1.0))
                continue
            spec = GoalSpec(target, planned.mode, *tolerance, rig.max_corrections,
                            planned.bound, tuple(site.camera), mode == Mode.AUTO)
            run = execute(spec, planned.plan, motion, rig.compensator, observe=observe)
            if planned.parts is not None and run.first is not None:
                online.account(pose_error(target, run.first), planned.parts, site.camera)
            rows.append((*pose_error(target, rig.arm.truth()), *planned.bound, 0.0))
        return rows

    if kind == 'auto':
        return {'auto': goals(model, '1', TARGET_SEED + 20 + seed)}
    phases = {'under_drift': goals(model, '1', TARGET_SEED + 30 + seed)}
    grown = region.grown(np.asarray(c['learner']['coverage_margin']))
    poses = refresh_poses(rig.geometry, grown, health.worst_joints(region_name, REFRESH_SAMPLES),
                          REFRESH_SAMPLES, seed=seed + 500)
    poses = poses[travel_order(poses, rig.arm.positions(), rig.geometry.velocity)]
    fresh: list[Any] = []
    Collector(motion, rig.geometry, c['learner']['measurement_retries'],
              clock=lambda: rig.arm.time).collect(poses, model.payload, fresh.append)
    mended = refreshed(model.predictor, rig.geometry, np.array([s.joints for s in fresh]),
                       np.array([s.deflection for s in fresh]),
                       np.full(len(fresh), model.payload), '2')
    phases['after_refresh'] = goals(AtPayload(mended, model.payload), '2',
                                    TARGET_SEED + 40 + seed)
    return phases


def phase_figures(rows: list[dict[str, Any]], phase: str,
                  tolerance: float = math.nan) -> dict[str, Any]:
    """Coverage by the truth, sharpness and (AUTO) unsafe goals of one phase, pooled."""
    goals = np.array([g for r in rows for g in r['phases'].get(phase, [])]).reshape(-1, 5)
    moved = goals[goals[:, 4] == 0]
    error, bound = moved[:, 0], moved[:, 2]
    return {'goals': len(goals), 'refused': int(np.sum(goals[:, 4])),
            'coverage': float(np.mean(error <= bound)) if len(moved) else math.nan,
            'median_bound_mm': 1e3 * float(np.median(bound)) if len(moved) else math.nan,
            'median_error_mm': 1e3 * float(np.median(error)) if len(moved) else math.nan,
            'sharpness': float(np.median(bound) / np.median(error)) if len(moved) else math.nan,
            'first_goal_errors_mm': [round(1e3 * r['phases'][phase][0][0], 4) for r in rows
                                     if r['phases'].get(phase)],
            'unsafe': int(np.sum(error > tolerance)) if tolerance == tolerance else None}


def scenario_figures(rows: list[dict[str, Any]]) -> dict[str, Any]:
    goals = np.array([g for r in rows for g in r['goals']]).reshape(-1, 5)
    error, bound = goals[:, 0], goals[:, 2]
    worst = int(np.argmax(error)) if len(goals) else 0
    return {'goals': len(goals), 'refused': sum(r['refused'] for r in rows),
            'out_of_reach': sum(r['out_of_reach'] for r in rows),
            'coverage': float(np.mean(error <= bound)) if len(goals) else math.nan,
            'angle_coverage': float(np.mean(goals[:, 1] <= goals[:, 3])) if len(goals)
            else math.nan,
            'median_bound_mm': 1e3 * float(np.median(bound)) if len(goals) else math.nan,
            'median_error_mm': 1e3 * float(np.median(error)) if len(goals) else math.nan,
            'max_error_mm': 1e3 * float(error[worst]) if len(goals) else math.nan,
            'bound_at_max_mm': 1e3 * float(bound[worst]) if len(goals) else math.nan,
            'unsafe_moves': int(np.sum((bound <= TOLERANCE) & (error > TOLERANCE))),
            'median_servo_bound_mm': 1e3 * float(np.median(goals[:, 4])) if len(goals)
            else math.nan,
            'wall_s': round(sum(r['wall_s'] for r in rows), 1)}


def mlp_fit_s(samples: int) -> tuple[float, float]:
    """Wall times of the MLP ensemble's fit on ``samples`` learning samples: the first in this
    process (torch imported, and its optimisers' first use: ~3 s, once per learner worker),
    and the next one, each fit after."""
    c = config()
    rig = Rig(c, set(SOURCES) - {'payload'}, 0.0, seed=0)
    region = configured_regions()['A']
    collected = collect(rig, region, samples, 0.0, 0, np.asarray(
        c['learner']['coverage_margin']), c['learner']['measurement_retries'])
    joints = np.array([s.joints for s in collected])
    deflections = np.array([s.deflection for s in collected])
    times = []
    for seed in (0, 1):
        started = time.perf_counter()
        make_predictor('mlp', {'seed': seed}).fit(joints, deflections)
        times.append(time.perf_counter() - started)
    return times[0], times[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--targets', type=int, default=15, help='targets per region and seed')
    parser.add_argument('--samples', type=int, default=40)
    parser.add_argument('--drift-goals', type=int, default=DRIFT_GOALS,
                        help='goals per phase after the change, per region and seed')
    parser.add_argument('--seeds', type=int, default=1)
    parser.add_argument('--regions', default='A,B')
    parser.add_argument('--kind', help="predictor kind (default: the learner's default_kind)")
    parser.add_argument('--only', help='comma-separated scenarios (default: every one)')
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--smoke', action='store_true',
                        help=f'{", ".join(SMOKE)}; 3 targets, 12 samples, region A, greybox')
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    args = parser.parse_args()
    if args.smoke:
        args.only, args.targets, args.samples, args.regions = ','.join(SMOKE), 3, 12, 'A'
        args.kind, args.workers, args.drift_goals = 'greybox', 1, 4
    names = args.only.split(',') if args.only else list(SCENARIOS)
    unknown = sorted(set(names) - set(SCENARIOS))
    if unknown:
        parser.error(f'unknown scenarios {unknown}; known: {", ".join(SCENARIOS)}')
    regions = args.regions.split(',')
    jobs = [(name, region, i, seed, args.samples, args.targets, args.kind or '', args.drift_goals)
            for name in names for i, region in enumerate(regions) for seed in range(args.seeds)]
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(run, jobs))
    scenarios = {name: scenario_figures([r for r in rows if r['name'] == name])
                 for name in names}
    print('scenario                  goals  coverage  median bound / error mm   max error mm '
          '(bound there)  refused  unsafe')
    for name, s in scenarios.items():
        print(f"{name:<25} {s['goals']:5d}  {s['coverage']:8.3f}  {s['median_bound_mm']:12.4f}"
              f" / {s['median_error_mm']:.4f}  {s['max_error_mm']:12.4f} "
              f"({s['bound_at_max_mm']:.4f})  {s['refused']:7d}  {s['unsafe_moves']:6d}",
              flush=True)
    pooled = [g for r in rows if r['name'] not in DRIFTING for g in r['goals']]
    judged = {name: s for name, s in scenarios.items() if name not in DRIFTING}
    nominal, payload = scenarios.get('nominal'), scenarios.get('payload_5kg')
    phases = {phase: phase_figures([r for r in rows if r['name'] == name], phase, tolerance)
              for name, phase, tolerance in (('drift_refresh', 'under_drift', math.nan),
                                             ('drift_refresh', 'after_refresh', math.nan),
                                             ('auto_drift', 'auto', AUTO_TOLERANCE[0]))
              if name in names}
    out: dict[str, Any] = {
        'coverage': (float(np.mean([g[0] <= g[2] for g in pooled])) if pooled else math.nan),
        'coverage_min': min((s['coverage'] for s in judged.values()), default=math.nan),
        'sharpness': (nominal['median_bound_mm'] / nominal['median_error_mm']
                      if nominal else math.nan),
        'sharpness_floor': (nominal['median_servo_bound_mm'] / nominal['median_error_mm']
                            if nominal else math.nan),
        'unsafe_moves': sum(s['unsafe_moves'] for s in judged.values()),
        **dict(zip(('mlp_first_fit_s', 'mlp_fit_s'),
                   (round(t, 3) for t in mlp_fit_s(args.samples)))),
        'coverage_under_drift': phases.get('under_drift', {}).get('coverage', math.nan),
        'coverage_after_refresh': phases.get('after_refresh', {}).get('coverage', math.nan),
        'sharpness_after_refresh': phases.get('after_refresh', {}).get('sharpness', math.nan),
        'auto_under_drift_unsafe': phases.get('auto', {}).get('unsafe'),
        'sharpness_payload': (payload['median_bound_mm'] / payload['median_error_mm']
                              if payload else math.nan),
        'coverage_payload': payload['coverage'] if payload else math.nan,
        'drift': scenarios.get('drift'), 'phases': phases, 'scenarios': scenarios,
        'targets_per_region': args.targets, 'samples': args.samples, 'seeds': args.seeds,
        'regions': regions}
    print(f"coverage {out['coverage']:.3f} (worst scenario {out['coverage_min']:.3f}), "
          f"sharpness {out['sharpness']:.2f} (floor {out['sharpness_floor']:.2f}), "
          f"unsafe moves {out['unsafe_moves']}, "
          f"MLP ensemble fit {out['mlp_fit_s']:.2f} s (the first {out['mlp_first_fit_s']:.2f} s)")
    for phase, f in phases.items():
        print(f"{phase:<25} {f['goals']:5d}  {f['coverage']:8.3f}  {f['median_bound_mm']:12.4f}"
              f" / {f['median_error_mm']:.4f}  refused {f['refused']}"
              + (f", unsafe {f['unsafe']}" if f['unsafe'] is not None else ''))
    if args.json:
        print(json.dumps(out))


if __name__ == '__main__':
    main()
