"""Input shaping: the tip's ringing after a move, the time from command to settled, and the
learning campaign's sim seconds per sample, per shaper (off, zv, zvd, ei).

Moves (pure core, fast): per region, ``--moves`` moves between consecutive random poses of the
region, each planned as the control nodes plan it (:class:`~flexarm_control.execution.
shaped_move.MovePlanner`: the synchronized profile within config/arm.yaml's limits, the shaper
at the nominal tip mode of ``arm.tip_mode`` for the payload and the target's No.2 arm length,
sampled every ``motion.trajectory_period``) and followed by the simulator's dynamics
(:class:`~flexarm_sim.dynamics.ArmDynamics`, config/sim.yaml's plant and tip mode, error
sources off: the ringing alone) from rest. ``residual_mm``: the largest distance of the tip
from its final static pose after the trajectory's end; ``settle_s``: from the command until
the tip stays within the vision node's settle window (config/vision.yaml
``settle.stability``, 0.02 mm) of that pose for good (the move's duration at least);
``settle_after_stop_s``: the part of it after the trajectory's end, the wait the ringing
costs; p95 and max over the moves of both regions, and per region. ``frequency_error``: the
same with the simulated arm's tip mode ``--frequency-error`` (15 %) below and above the table
the planner designs at (``residual_mm_p95``: the worse of the two).

Campaign (``--campaign N``, 0: skip): the graph as ``flexarm up`` starts it (realistic world,
×10 real time, or ``--rtf``), per shaper a collection of N samples per region through
/collect_samples; sim seconds per sample from the samples' stamps (first to last, over
N − 1), ``campaign_s_per_sample`` the mean over the regions; the arm carries ``--payload``
there too.

    python benchmarks/shaping.py [--moves 40] [--payload 0] [--campaign 20] [--json]
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from flexarm_core.joint_trajectory import SampledTrajectory
from flexarm_core.kinematics import ArmGeometry
from flexarm_core.params import load_config
from flexarm_core.regions import configured_regions
from flexarm_deflection.sampling import sample_poses
from flexarm_motion.shaped_move import MovePlanner
from flexarm_motion.shaping import KINDS
from flexarm_sim.dynamics import ArmDynamics
from flexarm_sim.plant import Plant

STEP = 0.01          # [s] of the simulator's joint states
AFTER = 8.0          # [s] followed after a trajectory's end (the slowest ring decays in ~6 s)


def world(payload: float, frequency_scale: float = 1.0) -> dict[str, Any]:
    """The simulator's arm (config/sim.yaml) with its tip mode scaled, and the nominal
    description and motion settings the control side plans with."""
    config = load_config('arm.yaml', 'sim.yaml', 'motion.yaml', node_name='flexarm_sim')
    config['settle'] = load_config('vision.yaml', node_name='flexarm_vision')['settle']
    dynamics = config['dynamics']
    table = dict(dynamics['natural_frequency'])
    table['hz'] = [f * frequency_scale for f in table['hz']]
    config['dynamics'] = {**dynamics, 'natural_frequency': table}
    config['plant'] = {**config['plant'], 'payload': payload}
    return config


def follow(config: dict[str, Any], geometry: ArmGeometry, planner: MovePlanner,
           start: np.ndarray, end: np.ndarray, payload: float, window: float
           ) -> tuple[float, float, float]:
    """One move from rest: the residual [m] after the trajectory, the time [s] from the
    command until the tip stays within ``window`` of its final static pose, and its part
    after the trajectory's end."""
    arm = ArmDynamics(Plant.from_dict(config['plant'], geometry), geometry, config['dynamics'],
                      start)
    move = planner.plan(start, end, payload)
    arm.follow(SampledTrajectory.from_points(start, move.times[1:], move.positions[1:],
                                             move.velocities[1:]))
    steps = int(round((move.duration + AFTER) / STEP))
    tips = np.empty((steps, 2))
    for k in range(steps):
        arm.step(STEP)
        tips[k] = arm.state.tip_pose[:2]
    final = Plant.from_dict(config['plant'], geometry).pose(end)[:2]
    off = np.hypot(*(tips - final).T)
    ended = int(round(move.duration / STEP))
    outside = np.nonzero(off > window)[0]
    settled = (outside[-1] + 1) * STEP if outside.size else 0.0
    return (float(off[ended:].max()), max(settled, move.duration),
            max(settled - move.duration, 0.0))


def moves(kind: str, payload: float, count: int, scale: float = 1.0) -> dict[str, Any]:
    """Residual and settle time of ``count`` moves per region with shaper ``kind``."""
    config = world(payload, scale)
    geometry = ArmGeometry.from_dict(config['arm'])
    planner = dataclasses.replace(MovePlanner.from_dicts(config['motion'], config['arm']),
                                  shaping=kind)
    window = float(config['settle']['stability'])
    out: dict[str, Any] = {}
    for name, region in configured_regions().items():
        if name not in ('A', 'B'):
            continue
        joints = sample_poses(geometry, region, count + 1, 'random', seed=7)[1]
        rows = [follow(config, geometry, planner, joints[i], joints[i + 1], payload, window)
                for i in range(count)]
        out[name] = np.array(rows)
    both = np.concatenate(list(out.values()))
    return {'residual_mm_p95': float(1e3 * np.percentile(both[:, 0], 95)),
            'residual_mm_max': float(1e3 * both[:, 0].max()),
            'settle_s_p95': float(np.percentile(both[:, 1], 95)),
            'settle_s_max': float(both[:, 1].max()),
            'settle_after_stop_s_p95': float(np.percentile(both[:, 2], 95)),
            'regions': {name: {'residual_mm_p95': float(1e3 * np.percentile(r[:, 0], 95)),
                               'settle_s_p95': float(np.percentile(r[:, 1], 95)),
                               'settle_after_stop_s_p95': float(np.percentile(r[:, 2], 95))}
                        for name, r in out.items()}}


def campaigns(kinds: list[str], count: int, rtf: float, payload: float
              ) -> dict[str, dict[str, float]]:
    """Sim seconds per sample of a graph collection of ``count`` per shaper and region, the arm
    carrying ``payload`` [kg] (the learner declares it; the simulator follows)."""
    from flexarm_bringup.supervisor import Graph
    from flexarm_cli.experiment import graph_client, reserved_domain
    from flexarm_core import topics
    from flexarm_msgs.msg import DeflectionSample

    out: dict[str, dict[str, float]] = {}
    for kind in kinds:
        with tempfile.TemporaryDirectory() as tmp, reserved_domain(None) as domain:
            run_dir = Path(tmp)
            shaping = {'motion.shaping': kind}
            parameters = {'flexarm_sim': {'real_time_factor': rtf},
                          'flexarm_learner': {'data_directory': str(run_dir / 'data'),
                                              'model_directory': str(run_dir / 'models'),
                                              'payload': payload, **shaping},
                          'flexarm_compensator': shaping}
            graph = Graph(domain, run_dir / 'run', parameters=parameters,
                          report=lambda _: None)
            with graph, graph_client(domain) as client:
                graph.wait_ready(120.0)
                client.wait_until_ready(timeout=30.0)
                samples: list[Any] = []
                client.create_subscription(DeflectionSample, topics.SAMPLES, samples.append,
                                           100)
                for region in ('A', 'B'):
                    samples.clear()
                    result = client.collect(count, region=region, seed=1,
                                            dataset=f'{kind}_{region}')
                    deadline = time.monotonic() + 10.0
                    while len(samples) < result.collected and time.monotonic() < deadline:
                        client.spin_once(0.02)
                    stamps = np.array([s.stamp.sec + 1e-9 * s.stamp.nanosec
                                       for s in samples[-result.collected:]])
                    out.setdefault(kind, {})[region] = float(
                        (stamps[-1] - stamps[0]) / (len(stamps) - 1))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--moves', type=int, default=40, help='moves per region')
    parser.add_argument('--payload', type=float, default=0.0, help='[kg]')
    parser.add_argument('--frequency-error', type=float, default=0.15)
    parser.add_argument('--campaign', type=int, default=20,
                        help='samples per graph collection (0: no graph)')
    parser.add_argument('--rtf', type=float, default=10.0,
                        help="the campaign graph's real-time factor")
    parser.add_argument('--shapers', default=','.join(KINDS))
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    nominal = load_config('arm.yaml', 'motion.yaml')
    default = MovePlanner.from_dicts(nominal['motion'], nominal['arm']).shaping   # auto: its pick
    out: dict[str, Any] = {'default': default, 'payload_kg': args.payload, 'shapers': {}}
    kinds = args.shapers.split(',')
    for kind in kinds:
        result = moves(kind, args.payload, args.moves)
        errors = {f'{scale:g}': moves(kind, args.payload, args.moves, scale)
                  for scale in (1 - args.frequency_error, 1 + args.frequency_error)}
        result['frequency_error'] = {
            'relative': args.frequency_error,
            'residual_mm_p95': max(e['residual_mm_p95'] for e in errors.values()),
            'settle_s_p95': max(e['settle_s_p95'] for e in errors.values()),
            'settle_after_stop_s_p95': max(e['settle_after_stop_s_p95']
                                           for e in errors.values()),
            'by_scale': errors}
        out['shapers'][kind] = result
        if not args.json:
            print(f'{kind:4s}: residual p95 {result["residual_mm_p95"]:.4f} mm, settle p95 '
                  f'{result["settle_s_p95"]:.2f} s ({result["settle_after_stop_s_p95"]:.2f} s '
                  f'after the stop); frequency ±{args.frequency_error:.0%}: '
                  f'residual p95 {result["frequency_error"]["residual_mm_p95"]:.4f} mm',
                  flush=True)
    if args.campaign:
        per_kind = campaigns(kinds, args.campaign, args.rtf, args.payload)
        for kind, regions in per_kind.items():
            out['shapers'][kind]['campaign_s_per_sample'] = float(np.mean(list(
                regions.values())))
            out['shapers'][kind]['campaign_regions'] = regions
    chosen = out['shapers'].get(default)
    if chosen is not None:
        out.update({key: chosen.get(key) for key in (
            'residual_mm_p95', 'settle_s_p95', 'settle_after_stop_s_p95',
            'campaign_s_per_sample')})
        out['frequency_error_residual_mm_p95'] = chosen['frequency_error']['residual_mm_p95']
    if 'off' in out['shapers']:
        off = out['shapers']['off']
        out['settle_s_p95_off'] = off['settle_s_p95']
        out['settle_after_stop_s_p95_off'] = off['settle_after_stop_s_p95']
    if args.json:
        print(json.dumps(out))
    else:
        print(json.dumps({k: v for k, v in out.items() if k != 'shapers'}, indent=1))


if __name__ == '__main__':
    main()
