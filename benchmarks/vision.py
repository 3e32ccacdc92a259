"""Vision accuracy and speed: random settled poses -> rendered image -> estimated tip pose.

Poses are drawn uniformly over x 0.6..1.7 m, y -0.7..0.4 m, phi -pi..pi; images are rendered
with noise, defocus and uneven illumination (config/camera.yaml), no motion. A *wrong cell* is
a valid estimate off by more than half the hole pitch (a decoding error, not imprecision).
The estimator's frame rate is measured on one core (cv2.setNumThreads(1)), as wall-clock and
as CPU time (the latter is not lowered by other processes competing for the core).

    python benchmarks/vision.py [--count N] [--seed S] [--json]
"""
from __future__ import annotations

import argparse
import json
import time

import cv2
import numpy as np

from flexarm_core.params import load_config
from flexarm_sim.camera import CameraRenderer
from flexarm_vision.pose_estimator import TipPoseEstimator

X_RANGE, Y_RANGE = (0.6, 1.7), (-0.7, 0.4)


def run(count: int, seed: int) -> dict[str, float]:
    cv2.setNumThreads(1)
    config = {**load_config('camera.yaml'),
              **load_config('vision.yaml', node_name='flexarm_vision')}
    renderer = CameraRenderer.from_dict(config)
    estimator = TipPoseEstimator.from_dict(config)
    rng = np.random.default_rng(seed)
    truth = np.column_stack([rng.uniform(*X_RANGE, count), rng.uniform(*Y_RANGE, count),
                             rng.uniform(-np.pi, np.pi, count)])
    images = [renderer.render(pose, rng=rng) for pose in truth]
    start, cpu_start = time.perf_counter(), time.process_time()
    estimates = [estimator.estimate(image) for image in images]
    elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu_start
    valid = np.array([e.valid for e in estimates])
    poses = np.array([e.pose for e in estimates if e.valid]).reshape(-1, 3)
    error_xy = poses[:, :2] - truth[valid, :2]
    error_phi = np.angle(np.exp(1j * (poses[:, 2] - truth[valid, 2])))
    distance = np.hypot(error_xy[:, 0], error_xy[:, 1])
    wrong = distance > renderer.plate.pitch / 2
    good = ~wrong
    return {
        'count': count,
        'valid_rate': float(valid.mean()),
        'wrong_cells': int(wrong.sum()),
        'position_error_mean_mm': float(distance[good].mean() * 1e3),
        'position_error_max_mm': float(distance[good].max() * 1e3),
        'position_bias_x_mm': float(error_xy[good, 0].mean() * 1e3),
        'position_bias_y_mm': float(error_xy[good, 1].mean() * 1e3),
        'angle_error_mean_deg': float(np.degrees(np.abs(error_phi[good]).mean())),
        'angle_error_max_deg': float(np.degrees(np.abs(error_phi[good]).max())),
        'angle_bias_deg': float(np.degrees(error_phi[good].mean())),
        'holes_used_min': int(min(e.holes_used for e in estimates if e.valid)),
        'holes_used_mean': float(np.mean([e.holes_used for e in estimates if e.valid])),
        'residual_mean_mm': float(np.mean([e.residual for e in estimates if e.valid]) * 1e3),
        'frames_per_second': count / elapsed,
        'frames_per_cpu_second': count / cpu,
        'invalid_reasons': sorted({e.status for e in estimates if not e.valid}),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--count', type=int, default=1000)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    args = parser.parse_args()
    r = run(args.count, args.seed)
    print(f"vision benchmark: {r['count']} random settled poses, 640x480, one core")
    print(f"  valid rate        {r['valid_rate']:.1%}   wrong cells {r['wrong_cells']}")
    print(f"  position error    mean {r['position_error_mean_mm']:.4f} mm   "
          f"max {r['position_error_max_mm']:.4f} mm   bias "
          f"({r['position_bias_x_mm']:+.4f}, {r['position_bias_y_mm']:+.4f}) mm")
    print(f"  angle error       mean {r['angle_error_mean_deg']:.5f} deg   "
          f"max {r['angle_error_max_deg']:.5f} deg   bias {r['angle_bias_deg']:+.5f} deg")
    print(f"  holes used        min {r['holes_used_min']}   mean {r['holes_used_mean']:.1f}   "
          f"fit residual mean {r['residual_mean_mm']:.4f} mm RMS")
    print(f"  estimator speed   {r['frames_per_second']:.0f} frames/s wall clock, "
          f"{r['frames_per_cpu_second']:.0f} frames per CPU second")
    if r['invalid_reasons']:
        print(f"  invalid because   {'; '.join(r['invalid_reasons'])}")
    if args.json:
        print(json.dumps(r))


if __name__ == '__main__':
    main()
