"""Error budget: what each error source of a real arm and camera costs PREDICTIVE and
CLOSED_LOOP, alone and all together, judged against the simulator's truth.

Offline and deterministic: the control core's own policies (the learner's collection loop and
training, the compensator's planning and goal execution,
:mod:`flexarm_motion.arm_motion` with config/motion.yaml's approach leg and averaging)
drive the simulated arm without its dynamics (:class:`flexarm_sim.static_arm.StaticArm`: the error
sources of config/sim.yaml ``error_sources`` at their configured magnitudes, images of the plate
rendered by the true camera and measured by the vision estimator with the calibrated one). Per
source set, region (A, B) and training seed (``--seeds``: its learning poses, joint errors and
image noise): ``--samples`` learning samples at the learner's poses, the learner's default
training, then ``--targets`` targets uniform in the region's box (the same for every seed and
set), each run PREDICTIVE (one move) and CLOSED_LOOP (corrected from the measured tip, the
compensator's tolerances). The error of a goal is its true tip pose against the target; the
figures pool every region and seed (``worst_run_*``: the worst single run), over the goals that
succeeded: ``failed`` counts the others (the user was told), ``refused`` PREDICTIVE refusals, and
``out_of_reach`` targets the sagging true arm cannot reach (robustness.py). Sim time runs on
through the campaign (travel time + 2 s settling per move), so thermal drift acts as it would
in an hour of work.

Sources (``sources`` in the JSON, each alone; ``all``: every one together; ``ideal``: none):
repeatability, hysteresis, thermal, camera as config/sim.yaml describes them; payload: the arm
picks up a ``--payload`` kg tool at run time before the campaign and learns with it (a model
that was not told is the model health's drift detection).

The camera source's floor (``sources.camera.before_mm``: the CLOSED_LOOP p95 with the camera
alone) comes from camera errors that are constant in the tool frame: the principal point
shifts every measured position by the same tool-frame vector, the mount yaw every angle. The
learner learns the camera's pose, not the tool's, and CLOSED_LOOP drives the camera's pose to
the target. ``sources.camera.after_mm``: the same after ``flexarm calibrate``'s procedure
(:func:`reference_calibration`: the camera against a reference instrument at the six Table 10
poses; a laser tracker's noise on the truth). ``sources.camera.sweep_after_mm``: after the
joint-4 sweep instead, the arm's own motion (:mod:`flexarm_control.execution.tool_calibration`
says why it cannot work; ``sweep.runs[*].calibration`` holds its estimate, the camera's true error
and the arm's own link-4 errors). ``all``: every source, calibrated by the reference procedure
as the realistic world is run; ``all_uncalibrated``: without it.

    python benchmarks/error_budget.py [--targets 200] [--samples 40] [--seeds 3] [--kind KIND]
        [--only SETS] [--json]

``--kind`` trains another predictor kind than the learner's default (a smoke run, a few
seconds, takes a cheap one: ``--seeds 1 --targets 2 --samples 12 --regions A --kind kinematic
--workers 1``).
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

from flexarm_control.execution.collection import Collector
from flexarm_control.execution.compensator import CompensationError, Compensator
from flexarm_control.execution.goal_execution import SUCCEEDED, GoalSpec, execute
from flexarm_control.execution.modes import Mode
from flexarm_control.execution.planning import DataLimits, Refusal, plan_goal
from flexarm_control.execution.tool_calibration import (
    calibrate_against_reference,
    fit_reference,
    joint4_sweep,
    sweep_joints,
)
from flexarm_core.kinematics import ArmGeometry, pose_error
from flexarm_core.measurement import Measurement
from flexarm_core.paper import TABLE_10
from flexarm_core.params import load_config
from flexarm_core.regions import configured_regions
from flexarm_core.tool_correction import ToolCorrection
from flexarm_deflection.cross_validation import Screening
from flexarm_deflection.sampling import random_targets, sample_poses, travel_order
from flexarm_deflection.selection import fit_robust
from flexarm_motion.arm_motion import Abort, ArmMotion, MotionSettings, never
from flexarm_sim.errors import ArmErrors
from flexarm_sim.plant import Plant
from flexarm_sim.static_arm import StaticArm
from flexarm_sim.true_camera import true_renderer
from flexarm_vision.pose_estimator import TipPoseEstimator

SOURCES = ('repeatability', 'hysteresis', 'thermal', 'payload', 'camera')
START = np.array([0.0, 0.6, 0.0, 0.0])
TARGET_SEED = 7000     # targets of a region: TARGET_SEED + its index (the same in every set)
TRACKER_SIGMA = np.array([1e-5, 1e-5, 2e-5])   # [m, m, rad] a laser tracker's reference noise


def config() -> dict[str, Any]:
    """Every tree the offline graph needs, as the nodes get them."""
    return {**load_config('arm.yaml', 'sim.yaml', 'camera.yaml'),
            **load_config('vision.yaml', node_name='flexarm_vision'),
            'learner': load_config('learner.yaml', node_name='flexarm_learner'),
            'compensator': load_config('motion.yaml', 'compensator.yaml',
                                       node_name='flexarm_compensator')}


def error_sources(base: dict[str, Any], on: set[str]) -> dict[str, Any]:
    """config/sim.yaml's ``error_sources`` with exactly the sources ``on`` switched on."""
    tree = copy.deepcopy(base)
    tree['enabled'] = bool(on)
    for source in SOURCES:
        tree[source]['enabled'] = source in on
    return tree


class Rig:
    """The static arm of one source set, and the control core that drives it."""

    def __init__(self, c: dict[str, Any], on: set[str], payload: float, seed: int) -> None:
        self.geometry = ArmGeometry.from_dict(c['arm'])
        sources = error_sources(c['error_sources'], on)
        plant = Plant.from_dict(c['plant'], self.geometry)
        if 'payload' in on:
            plant = plant.with_payload(payload)
        vision = {key: c[key] for key in ('plate', 'camera', 'camera_render', 'vision')}
        self.arm = StaticArm(plant, ArmErrors.from_dict(sources, plant.backlash), START,
                             true_renderer(vision, sources),
                             TipPoseEstimator.from_dict(vision), np.random.default_rng(seed))
        comp = c['compensator']
        self.compensator = Compensator(self.geometry, comp['compensation'])
        self.limits = DataLimits(comp['max_data_distance'], comp['max_prediction_std'])
        self.tolerance = (comp['position_tolerance'], comp['angle_tolerance'])
        self.max_corrections = comp['max_corrections']
        self.motion = ArmMotion(self.arm, self.geometry, MotionSettings.from_dict(comp['motion']))
        self.payload = payload if 'payload' in on else 0.0
        self.correction = ToolCorrection()


def run(job: tuple[str, tuple[str, ...], str, int, int, int, int, float, str, str]
        ) -> dict[str, Any]:
    """One source set in one region with one training seed: learn, then every target in
    both modes."""
    name, on, region_name, region_index, seed, samples, targets, payload, calibrate, kind = job
    started = time.perf_counter()
    c = config()
    rig = Rig(c, set(on), payload, seed=100 * seed + region_index)
    learner = c['learner']
    regions = configured_regions()
    calibration = None
    if calibrate:
        calibration = CALIBRATIONS[calibrate](rig, regions[region_name])
        rig.correction = calibration.pop('correction')
    motion = CalibratedMotion(rig)
    _, poses = sample_poses(rig.geometry, regions[region_name].grown(
        np.asarray(learner['coverage_margin'])), samples, 'sobol', seed=100 * seed + region_index)
    poses = poses[travel_order(poses, rig.arm.positions(), rig.geometry.velocity)]
    collected = []
    Collector(motion, rig.geometry, learner['measurement_retries'],
              clock=lambda: rig.arm.time).collect(poses, rig.payload, collected.append)
    joints = np.array([s.joints for s in collected])
    deflections = np.array([s.deflection for s in collected])
    predictor, _ = fit_robust(kind or learner['default_kind'], {}, joints, deflections,
                              folds=learner['validation_folds'], geometry=rig.geometry,
                              screening=Screening.from_dict(learner['training']))
    learned_at = rig.arm.time
    errors: dict[str, list[tuple[float, float]]] = {'predictive': [], 'closed_loop': []}
    refused, failed, out_of_reach, moves = 0, 0, 0, []
    for target in random_targets(rig.geometry, regions[region_name], targets,
                                 TARGET_SEED + region_index):
        try:        # can the true arm reach it? (robustness.py: the sag near the edge)
            rig.compensator.predictive(target, rig.arm.plant.deflection)
        except CompensationError:
            out_of_reach += 1
            continue
        for mode in (Mode.PREDICTIVE, Mode.CLOSED_LOOP):
            planned = plan_goal(rig.compensator, mode, target, predictor, rig.limits)
            if isinstance(planned, Refusal):
                refused += 1
                continue
            closed = mode == Mode.CLOSED_LOOP
            spec = GoalSpec(target, mode, *(rig.tolerance if closed else (0.0, 0.0)),
                            rig.max_corrections)
            outcome = execute(spec, planned.plan, motion, rig.compensator)
            if outcome.status != SUCCEEDED:      # the user is told: no silent miss
                failed += 1
                continue
            if closed:
                moves.append(outcome.moves)
            position, angle = pose_error(target, rig.arm.truth())
            errors[mode.label].append((1e3 * position, math.degrees(angle)))
    return {'name': name, 'region': region_name, 'seed': seed, 'samples': len(collected),
            'refused': refused, 'failed': failed, 'out_of_reach': out_of_reach,
            'errors': errors,
            'closed_loop_moves': float(np.mean(moves)) if moves else 0.0,
            'campaign_h': rig.arm.time / 3600, 'learned_at_h': learned_at / 3600,
            'calibration': calibration,
            'wall_s': time.perf_counter() - started}


class CalibratedMotion(ArmMotion):
    """The rig's motion whose measurements pass through its tool calibration."""

    def __init__(self, rig: Rig) -> None:
        super().__init__(rig.arm, rig.geometry, rig.motion.settings)
        self._rig = rig

    def measure(self, abort: Abort = never) -> Measurement | None:
        measurement = super().measure(abort)
        return None if measurement is None else self._rig.correction.apply(measurement)


def collect(rig: Rig, region: Any, count: int, kg: float, seed: int,
            coverage: np.ndarray, retries: int) -> list[Any]:
    """The learner's samples at ``count`` Sobol poses of ``region`` grown by ``coverage``,
    the arm carrying ``kg``, in travel order (its collection loop, through the tool
    calibration)."""
    rig.arm.set_payload(kg)
    _, poses = sample_poses(rig.geometry, region.grown(coverage), count, 'sobol', seed=seed)
    poses = poses[travel_order(poses, rig.arm.positions(), rig.geometry.velocity)]
    collected: list[Any] = []
    Collector(CalibratedMotion(rig), rig.geometry, retries,
              clock=lambda: rig.arm.time).collect(poses, kg, collected.append)
    return collected


def camera_error(rig: Rig, joints: np.ndarray) -> ToolCorrection:
    """The camera's true error in the tool frame at ``joints`` (measured against the truth)."""
    rig.motion.move_to(joints)
    return fit_reference(rig.motion.measure().pose, rig.arm.truth())


def reference_calibration(rig: Rig, region: Any) -> dict[str, Any]:
    """``flexarm calibrate``'s procedure: RIGID moves to the Table 10 targets, camera against a
    reference instrument (the truth plus a laser tracker's noise, ``TRACKER_SIGMA``)."""
    rng = np.random.default_rng(99)

    def measure(target: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        rig.motion.move_to(rig.compensator.rigid(target).joints)
        measurement = rig.motion.measure()
        if measurement is None:
            return None
        return measurement.pose, rig.arm.truth() + rng.normal(0.0, TRACKER_SIGMA)

    found = calibrate_against_reference([t.pose for t in TABLE_10], measure)
    truth = camera_error(rig, rig.compensator.rigid(TABLE_10[0].pose).joints)
    return {'correction': found.correction, 'estimated': _mm_deg(found.correction),
            'true_camera_error': _mm_deg(truth), 'poses': found.poses,
            'spread_mm': 1e3 * found.spread[0]}


def sweep_calibration(rig: Rig, region: Any) -> dict[str, Any]:
    """The joint-4 sweep at the region's centre, against the camera's true error and the
    arm's own link-4 errors it cannot be told apart from."""
    centre = rig.compensator.rigid((region.lower + region.upper) / 2).joints
    measured, used = [], []
    for joints in sweep_joints(centre, rig.geometry):
        rig.motion.move_to(joints)
        measurement = rig.motion.measure()
        if measurement is not None:
            measured.append(measurement.pose)
            used.append(joints)
    correction = joint4_sweep(np.array(used), np.array(measured), rig.geometry)
    plant = rig.arm.plant
    return {'correction': correction, 'estimated': _mm_deg(correction),
            'true_camera_error': _mm_deg(camera_error(rig, centre)),
            'link4_fabrication_error_mm': 1e3 * float(plant.link4_error),
            'joint4_zero_error_deg': math.degrees(float(plant.joint_zero_error[3])),
            'poses': len(measured)}


def _mm_deg(c: ToolCorrection) -> dict[str, float]:
    return {'axial_mm': 1e3 * c.axial, 'lateral_mm': 1e3 * c.lateral,
            'angle_deg': math.degrees(c.angle)}


CALIBRATIONS = {'reference': reference_calibration, 'sweep': sweep_calibration}


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Worst-case figures over the regions of one source set."""
    out: dict[str, Any] = {'refused': sum(r['refused'] for r in rows),
                           'failed': sum(r['failed'] for r in rows),
                           'out_of_reach': sum(r['out_of_reach'] for r in rows),
                           'closed_loop_moves': max(r['closed_loop_moves'] for r in rows)}
    for mode in ('predictive', 'closed_loop'):
        e = np.array([x for r in rows for x in r['errors'][mode]]).reshape(-1, 2)
        out[f'{mode}_p95_mm'] = float(np.percentile(e[:, 0], 95)) if len(e) else math.nan
        out[f'{mode}_max_mm'] = float(e[:, 0].max(initial=0.0))
        out[f'{mode}_p95_deg'] = float(np.percentile(e[:, 1], 95)) if len(e) else math.nan
        out[f'{mode}_max_deg'] = float(e[:, 1].max(initial=0.0))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--targets', type=int, default=200, help='targets per region')
    parser.add_argument('--samples', type=int, default=40)
    parser.add_argument('--seeds', type=int, default=3,
                        help='training seeds (learning poses and image noise) per region')
    parser.add_argument('--regions', default='A,B')
    parser.add_argument('--payload', type=float, default=5.0, help='[kg] the payload source')
    parser.add_argument('--only', help='comma-separated source sets (default: every one)')
    parser.add_argument('--kind', help="predictor kind (default: the learner's default_kind)")
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    args = parser.parse_args()
    sets = {'ideal': (), **{s: (s,) for s in SOURCES}, 'all': SOURCES,
            'camera_calibrated': ('camera',), 'camera_sweep': ('camera',),
            'all_calibrated': SOURCES}
    calibration = {'camera_calibrated': 'reference', 'all_calibrated': 'reference',
                   'camera_sweep': 'sweep'}
    chosen = args.only.split(',') if args.only else list(sets)
    regions = args.regions.split(',')
    jobs = [(name, sets[name], region, i, seed, args.samples, args.targets, args.payload,
             calibration.get(name, ''), args.kind or '')
            for name in chosen for i, region in enumerate(regions)
            for seed in range(args.seeds)]
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(run, jobs))
    results: dict[str, Any] = {}
    print('sources            PRED p95 mm  max mm  p95 deg | CL p95 mm  max mm  p95 deg | '
          'CL moves  refused  failed  out of reach')
    for name in chosen:
        mine = [r for r in rows if r['name'] == name]
        results[name] = s = summary(mine)
        s['runs'] = [{k: v for k, v in r.items() if k != 'errors'} for r in mine]
        s['worst_run_closed_loop_p95_mm'] = max(summary([r])['closed_loop_p95_mm']
                                                for r in mine)
        s['worst_run_predictive_p95_mm'] = max(summary([r])['predictive_p95_mm']
                                               for r in mine)
        print(f"{name:<18} {s['predictive_p95_mm']:11.3f} {s['predictive_max_mm']:7.3f} "
              f"{s['predictive_p95_deg']:8.4f} | {s['closed_loop_p95_mm']:9.3f} "
              f"{s['closed_loop_max_mm']:7.3f} {s['closed_loop_p95_deg']:8.4f} | "
              f"{s['closed_loop_moves']:8.2f} {s['refused']:8d} {s['failed']:7d} "
              f"{s['out_of_reach']:13d}", flush=True)
    out: dict[str, Any] = {'targets_per_region': args.targets, 'samples': args.samples,
                           'seeds': args.seeds,
                           'regions': regions, 'payload_kg': args.payload,
                           'sources': {k: v for k, v in results.items()
                                       if k in SOURCES or k == 'ideal'}}
    if 'camera' in results:
        camera = out['sources']['camera']
        camera['before_mm'] = camera['closed_loop_p95_mm']
        if 'camera_calibrated' in results:
            camera['after_mm'] = results['camera_calibrated']['closed_loop_p95_mm']
            camera['calibrated'] = results['camera_calibrated']
        if 'camera_sweep' in results:
            camera['sweep_after_mm'] = results['camera_sweep']['closed_loop_p95_mm']
            camera['sweep'] = results['camera_sweep']
    if 'all_calibrated' in results:      # the realistic world as it is run: calibrated
        out['all'] = results['all_calibrated']
        if 'all' in results:
            out['all_uncalibrated'] = results['all']
    elif 'all' in results:
        out['all'] = results['all']
    if args.json:
        print(json.dumps(out))


if __name__ == '__main__':
    main()
