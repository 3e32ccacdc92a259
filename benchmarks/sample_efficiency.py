"""Sample efficiency: learning curves of the collection strategies, and sim seconds per sample.

Learning curves (offline, pure core, the realistic world): the learner's collection loop
(:class:`~flexarm_control.execution.collection.Collector`, config/motion.yaml's approach leg and
averaging) drives the simulated arm without its dynamics
(:class:`flexarm_sim.static_arm.StaticArm`, config/sim.yaml's error sources: repeatability,
friction hysteresis, thermal drift, the true camera; the camera calibrated against the reference
first, as the realistic world is run; error_budget.py's rig). Per strategy (sobol: the learner's
poses, visited in travel order; active: :mod:`flexarm_deflection.active_sampling`), region
(A, B) and seed (its poses, joint errors and image noise) one campaign of the largest sample count;
the curve at n samples fits the learner's model selection
(:func:`~flexarm_deflection.selection.fit_robust`, each ``--kinds``) on the first n poses of
the strategy's sequence (Sobol order for sobol, the order chosen for active) and judges it on
``--held-out`` poses uniform in the region's box against the plant's TRUE deflection there
(approached from below as every move is, at the campaign's end temperature). Errors: position |(dx,
dy)| mm and |dφ| deg, max and 95th percentile over the held-out poses (NaN, and counted in
``refused``, where training refused the data: the user gets no model); ``samples_for_1mm``: the
smallest n of the grid from which the max position error stays below 1 mm for every seed (null:
never); ``samples_for_1mm`` and ``curves`` of the first of ``--kinds`` at the top level, of every
kind under ``by_kind``. ``offline``: per strategy, the travel between consecutive poses at the
Table 1 speeds (the first leg, from the start, left out) and the wall time of choosing the active
poses. A full run (5 seeds, kinds gp and auto, campaigns of 20) takes about 10 minutes on 2 cores.

Campaign (``--campaign N``, 0: skip): the graph as ``flexarm up`` starts it (realistic world,
×10 real time), the tool calibration of ``flexarm calibrate``, then per strategy and region a
real collection of N samples through the learner's /collect_samples; sim seconds per sample
from the samples' stamps (first to last, over N − 1; ``campaign_s_per_sample``: the mean
over the regions per strategy), and the measured-minus-true tip pose of every sample
(``/sim/tip_pose_truth`` at its stamp): its scatter about the campaign's median is the
measurement's quality (``--measurement-frames`` compares the learner's averaging).

    python benchmarks/sample_efficiency.py [--seeds 5] [--held-out 200] [--kinds gp,auto]
        [--campaign 20] [--measurement-frames N] [--workers 2] [--json]
"""
from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from error_budget import SOURCES, CalibratedMotion, Rig, config, reference_calibration

from flexarm_control.execution.collection import Collector
from flexarm_core.kinematics import forward, wrap_angle
from flexarm_core.regions import configured_regions
from flexarm_deflection.active_sampling import ActivePoses, ActiveSettings, run_now
from flexarm_deflection.cross_validation import Screening
from flexarm_deflection.dataset import Sample
from flexarm_deflection.sampling import path_time, sample_poses, travel_order
from flexarm_deflection.selection import fit_robust

COUNTS = (8, 10, 12, 15, 20, 25, 30, 40)
STRATEGIES = ('sobol', 'active')
REALISTIC = tuple(s for s in SOURCES if s != 'payload')   # the graph's world: no payload
HELD_OUT_SEED = 1000


def true_deflection(rig: Rig, joints: np.ndarray, approach: np.ndarray) -> np.ndarray:
    """The plant's deflection (n, 3) at ``joints`` approached by ``approach`` from below (the
    friction band taken up), at the rig's current temperature; no servo error."""
    errors, plant = rig.arm.errors, rig.arm.plant
    play = errors.slip(np.zeros(4), approach)
    d = plant.pose(joints, errors.band * play, errors.strain(rig.arm.time)) - forward(
        rig.geometry, joints)
    d[:, 2] = wrap_angle(d[:, 2])
    return d


def campaign(job: tuple[str, str, int, int, tuple[int, ...], tuple[str, ...], int, float]
             ) -> dict[str, Any]:
    """One strategy in one region with one seed: collect, then the curve of every kind."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)
    strategy, region_name, region_index, seed, counts, kinds, held_out, near_best = job
    started = time.perf_counter()
    c = config()
    learner = c['learner']
    regions = configured_regions()
    rig = Rig(c, set(REALISTIC), 0.0, seed=100 * seed + region_index)
    rig.correction = reference_calibration(rig, regions[region_name])['correction']
    motion = CalibratedMotion(rig)
    grown = regions[region_name].grown(np.asarray(learner['coverage_margin']))
    largest = max(counts)
    collected: list[Sample] = []
    rank: list[int] = []          # per sample: its place in the strategy's sequence

    def arrays() -> tuple[np.ndarray, np.ndarray]:
        return (np.array([s.joints for s in collected]).reshape(-1, 4),
                np.array([s.deflection for s in collected]).reshape(-1, 3))

    start = rig.arm.positions()
    choosing = [0.0]        # [s, wall] spent choosing active poses

    def timed(job: Any, *job_args: Any) -> Any:
        tick = time.perf_counter()
        future = run_now(job, *job_args)
        choosing[0] += time.perf_counter() - tick
        return future

    if strategy == 'active':
        sequence = np.arange(largest)
        plan: Any = ActivePoses(rig.geometry, grown, largest, seed, arrays, start, timed,
                                ActiveSettings(near_best=near_best))
    else:
        _, planned = sample_poses(rig.geometry, grown, largest, strategy, seed)
        sequence = travel_order(planned, start, rig.geometry.velocity)
        plan = planned[sequence]
    visited: list[np.ndarray] = []

    def record(k: int, _: Any, sample: Sample | None) -> None:
        if sample is not None:
            rank.append(int(sequence[k - 1]))

    t0, moves0 = rig.arm.time, rig.arm.moves
    Collector(motion, rig.geometry, learner['measurement_retries'],
              clock=lambda: rig.arm.time).collect(
        _watch(plan, visited), 0.0, collected.append, progress=record)
    campaign_s = rig.arm.time - t0
    travel_s = path_time(np.array(visited[1:]), visited[0], rig.geometry.velocity)
    joints, deflections = arrays()
    by_rank = np.argsort(rank, kind='stable')
    joints, deflections, rank = joints[by_rank], deflections[by_rank], np.array(rank)[by_rank]
    _, test_q = sample_poses(rig.geometry, regions[region_name], held_out, 'random',
                             HELD_OUT_SEED + seed)
    truth = true_deflection(rig, test_q, rig.motion.settings.approach)
    screening = Screening.from_dict(learner['training'])
    curves: dict[str, list[dict[str, Any]]] = {}
    for kind in kinds:
        curves[kind] = []
        for n in counts:
            use = rank < n
            try:
                predictor, _ = fit_robust(kind, {}, joints[use], deflections[use],
                                          folds=learner['validation_folds'],
                                          geometry=rig.geometry, screening=screening)
            except ValueError as exc:      # training refused: the user gets no model (NaN)
                curves[kind].append({'samples': n, 'measured': int(use.sum()),
                                     'refused': str(exc), **dict.fromkeys(
                                         ('max_mm', 'p95_mm', 'max_deg', 'p95_deg'), math.nan)})
                continue
            err = np.abs(predictor.predict(test_q) - truth)
            position = 1e3 * np.hypot(err[:, 0], err[:, 1])
            angle = np.degrees(err[:, 2])
            curves[kind].append({
                'samples': n, 'measured': int(use.sum()),
                'max_mm': float(position.max()), 'p95_mm': float(np.percentile(position, 95)),
                'max_deg': float(angle.max()), 'p95_deg': float(np.percentile(angle, 95))})
    return {'strategy': strategy, 'region': region_name, 'seed': seed,
            'samples': len(collected), 'moves': rig.arm.moves - moves0,
            'travel_s_per_sample': travel_s / max(1, len(visited) - 1),
            'offline_campaign_s': campaign_s, 'selection_wall_s': choosing[0],
            'curves': curves, 'wall_s': time.perf_counter() - started}


def _watch(poses: Any, visited: list[np.ndarray]) -> Any:
    """``poses``, each also appended to ``visited`` as it is handed out."""
    for q in poses:
        visited.append(np.asarray(q))
        yield q


def samples_for_1mm(runs: list[dict[str, Any]], kind: str) -> int | None:
    """The smallest n from which the max error stays < 1 mm for every run (None: never)."""
    counts = [p['samples'] for p in runs[0]['curves'][kind]]
    worst = np.max([[p['max_mm'] for p in r['curves'][kind]] for r in runs], axis=0)
    below = worst < 1.0
    for i, n in enumerate(counts):
        if below[i:].all():
            return n
    return None


def summary(rows: list[dict[str, Any]], kinds: tuple[str, ...]) -> dict[str, Any]:
    """Per kind, strategy and region: the curves (worst and mean over seeds), samples_for_1mm."""
    out: dict[str, Any] = {}
    for kind in kinds:
        by: dict[str, Any] = {'samples_for_1mm': {}, 'curves': {}}
        for strategy in sorted({r['strategy'] for r in rows}):
            by['samples_for_1mm'][strategy], by['curves'][strategy] = {}, {}
            for region in sorted({r['region'] for r in rows}):
                runs = [r for r in rows if (r['strategy'], r['region']) == (strategy, region)]
                if not runs:
                    continue
                by['samples_for_1mm'][strategy][region] = samples_for_1mm(runs, kind)
                points = []
                for i, p in enumerate(runs[0]['curves'][kind]):
                    per_seed = [r['curves'][kind][i] for r in runs]
                    points.append({'samples': p['samples'],
                                   'refused': sum('refused' in q for q in per_seed), **{
                        f'{stat}_{key}': float(fn([q[key] for q in per_seed]))
                        for key in ('max_mm', 'p95_mm', 'max_deg', 'p95_deg')
                        for stat, fn in (('worst', np.max), ('mean', np.mean))}})
                by['curves'][strategy][region] = points
        out[kind] = by
    return out


def graph_campaigns(count: int, regions: list[str], frames: int | None) -> dict[str, Any]:
    """Real collections on the running graph (module docstring): per strategy and region."""
    from flexarm_bringup.supervisor import Graph
    from flexarm_cli.calibration import calibrate_tool
    from flexarm_cli.experiment import graph_client, reserved_domain
    from flexarm_core import topics
    from flexarm_msgs.msg import DeflectionSample, TipPose

    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp, reserved_domain(None) as domain:
        run_dir = Path(tmp)
        learner: dict[str, Any] = {'data_directory': str(run_dir / 'data'),
                                   'model_directory': str(run_dir / 'models')}
        if frames is not None:
            learner['motion.measurement_frames'] = frames
        parameters = {'flexarm_sim': {'real_time_factor': 10.0}, 'flexarm_learner': learner,
                      'flexarm_vision': {'tool_calibration_file': str(run_dir / 'tool.json')}}
        graph = Graph(domain, run_dir / 'run', parameters=parameters, report=lambda _: None)
        with graph, graph_client(domain) as client:
            graph.wait_ready(120.0)
            client.wait_until_ready(timeout=30.0)
            calibrate_tool(client, topics.TIP_POSE_TRUTH, run_dir / 'tool.json',
                           say=lambda _: None)
            samples: list[Any] = []
            truth: list[tuple[float, float, float, float]] = []
            client.create_subscription(DeflectionSample, topics.SAMPLES, samples.append, 100)
            client.create_subscription(TipPose, topics.TIP_POSE_TRUTH, lambda m: truth.append(
                (_seconds(m.header.stamp), m.pose.x, m.pose.y, m.pose.phi)), 1000)
            for strategy in STRATEGIES:
                for region in regions:
                    samples.clear()
                    wall = time.monotonic()
                    result = client.collect(count, region=region, strategy=strategy, seed=1,
                                            dataset=f'{strategy}_{region}')
                    wall = time.monotonic() - wall
                    # this goal's last sample messages: queued behind ~1000 truth poses a
                    # second (100 Hz x10), so wait for them, not for a number of callbacks
                    deadline = time.monotonic() + 10.0
                    while len(samples) < result.collected and time.monotonic() < deadline:
                        client.spin_once(0.02)
                    del samples[:-result.collected or len(samples)]   # this goal's only
                    stamps = np.array([_seconds(s.stamp) for s in samples])
                    t = np.array([p[0] for p in truth])
                    at = np.abs(t[None, :] - stamps[:, None]).argmin(axis=1)
                    known = np.abs(t[at] - stamps) < 0.05   # [s] a truth pose at the stamp
                    true_pose = np.array([truth[i][1:] for i in at[known]])
                    measured = np.array([[s.measured_pose.x, s.measured_pose.y,
                                          s.measured_pose.phi] for s in samples])[known]
                    miss = measured - true_pose if known.any() else np.full((1, 3), np.nan)
                    scatter = 1e3 * np.hypot(*(miss[:, :2] - np.median(miss[:, :2], axis=0)).T)
                    out.setdefault(strategy, {})[region] = {
                        'collected': int(result.collected), 'skipped': int(result.skipped),
                        'error_code': int(result.error_code),
                        's_per_sample': float((stamps[-1] - stamps[0]) / (len(stamps) - 1)),
                        'wall_s': wall,
                        'measured_minus_true_mm': {'samples': int(known.sum()),
                            'bias': (1e3 * np.median(miss[:, :2], axis=0)).tolist(),
                            'scatter_max': float(scatter.max()),
                            'scatter_rms': float(np.sqrt(np.mean(scatter ** 2)))}}
                    truth.clear()
    return out


def _seconds(stamp: Any) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seeds', type=int, default=5)
    parser.add_argument('--regions', default='A,B')
    parser.add_argument('--counts', default=','.join(map(str, COUNTS)),
                        help='sample counts of the curves (each >= 8: k-fold training)')
    parser.add_argument('--held-out', type=int, default=200, help='held-out poses per seed')
    parser.add_argument('--kinds', default='',
                        help="comma-separated predictor kinds (default: the learner's)")
    parser.add_argument('--strategies', default=','.join(STRATEGIES))
    parser.add_argument('--near-best', type=float, default=ActiveSettings.near_best,
                        help='active: the nearest candidate within this x the largest std')
    parser.add_argument('--campaign', type=int, default=20,
                        help='samples per graph collection (0: no graph)')
    parser.add_argument('--measurement-frames', type=int,
                        help='graph: the learner\'s motion.measurement_frames (default: config)')
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    args = parser.parse_args()
    c = config()
    kinds = tuple(args.kinds.split(',')) if args.kinds else (c['learner']['default_kind'],)
    regions = args.regions.split(',')
    counts = tuple(sorted(int(n) for n in args.counts.split(',')))
    started = time.monotonic()
    out: dict[str, Any] = {'seeds': args.seeds, 'regions': regions, 'counts': counts,
                           'held_out': args.held_out, 'kinds': kinds,
                           'world': 'realistic, camera calibrated',
                           'near_best': args.near_best}
    rows: list[dict[str, Any]] = []
    if args.seeds > 0:
        jobs = [(strategy, region, i, seed, counts, kinds, args.held_out, args.near_best)
                for strategy in args.strategies.split(',') for i, region in enumerate(regions)
                for seed in range(args.seeds)]
        with ProcessPoolExecutor(args.workers) as pool:
            rows = list(pool.map(campaign, jobs))
        results = summary(rows, kinds)
        out.update(results[kinds[0]])
        out['by_kind'] = results
        out['offline'] = {s: {
            'travel_s_per_sample': float(np.mean([r['travel_s_per_sample'] for r in rows
                                                  if r['strategy'] == s])),
            'selection_wall_s_per_sample': float(np.mean([
                r['selection_wall_s'] / r['samples'] for r in rows if r['strategy'] == s]))}
            for s in sorted({r['strategy'] for r in rows})}
        for kind in kinds:
            print(f'{kind}: samples for < 1 mm max error (worst of {args.seeds} seeds): '
                  f"{results[kind]['samples_for_1mm']}")
            for strategy, per_region in results[kind]['curves'].items():
                for region, points in per_region.items():
                    print(f'  {strategy:<7} {region}: ' + '  '.join(
                        f"{p['samples']}: {p['worst_max_mm']:.2f}/{p['worst_p95_mm']:.2f}"
                        for p in points) + '  (n: worst max / p95 mm)', flush=True)
        print(f"travel per sample (Table 1 speeds): {out['offline']}")
    if args.campaign:
        graph = graph_campaigns(args.campaign, regions, args.measurement_frames)
        out['campaign'] = graph
        out['campaign_s_per_sample'] = {
            s: float(np.mean([r['s_per_sample'] for r in per.values()]))
            for s, per in graph.items()}
        print(f"graph campaigns of {args.campaign} samples: sim s per sample "
              f"{out['campaign_s_per_sample']}")
    out['elapsed_s'] = time.monotonic() - started
    if args.json:
        print(json.dumps(out))


if __name__ == '__main__':
    main()
