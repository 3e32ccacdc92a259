"""Cameras that differ from their calibration: how many frames the vision still measures, and how
far off the measured tip is, before and after the reference calibration (``flexarm calibrate``).

Each case renders settled tip poses with a true camera whose focal length, principal point,
k1, k2 or mount yaw (each alone, then all together) differs from the calibration the estimator
believes by 1, 3, 5 and 10 times the realistic world's error (config/sim.yaml
``error_sources.camera``; the plate's hole errors stay as there). Poses are drawn over the
paper's regions A and B (x 1.0..1.6 m, y -0.5..0.15 m, phi -100..-6 deg, Table 10's span).
Per case: ``valid_fraction`` of the frames, ``before_mm`` the 95th percentile of the valid
frames' position error against the true tip, ``after_reference_mm`` the same once the tool
correction fitted at the six Table 10 poses (as ``flexarm calibrate`` does, with the true tip
as the reference) is applied. ``after_mm`` is the same error once the camera's own parameters
are first calibrated from the plate images at those six poses and then the reference
calibration is made through them (``flexarm calibrate --camera``); ``after_valid_fraction``
the valid frames through the calibrated camera. ``worst`` holds the smallest valid fractions
and the largest errors up to 5 times, ``worst_10x`` at 10 times (null without that scale).

    python benchmarks/camera_robustness.py [--poses 40] [--seed 0] [--json]
"""
from __future__ import annotations

import argparse
import copy
import json
import math
from typing import Any

import cv2
import numpy as np

from flexarm_control.execution.tool_calibration import calibrate_against_reference
from flexarm_core.paper import TABLE_10
from flexarm_core.params import load_config
from flexarm_sim.true_camera import true_renderer
from flexarm_vision.camera_calibration import calibrate_camera
from flexarm_vision.pose_estimator import Estimate, TipPoseEstimator

SCALES = (1, 3, 5, 10)
ERRORS = ('focal_length', 'principal_point', 'k1', 'k2', 'mount_yaw')
X_RANGE, Y_RANGE, PHI_RANGE = (1.0, 1.6), (-0.5, 0.15), (math.radians(-100), math.radians(-6))


def scaled_errors(sources: dict[str, Any], which: tuple[str, ...], scale: float
                  ) -> dict[str, Any]:
    """config/sim.yaml's error sources with only the camera on, ``which`` of its errors
    ``scale`` times as large and the others 0 (the hole errors kept)."""
    out = copy.deepcopy(sources)
    out['enabled'] = True
    for name, source in out.items():
        if isinstance(source, dict) and 'enabled' in source:
            source['enabled'] = name == 'camera'
    camera = out['camera']
    for name in ERRORS:
        value = np.asarray(camera[name], dtype=float) * (scale if name in which else 0.0)
        camera[name] = value.tolist()
    camera['mount_offset'] = [0.0, 0.0]
    return out


def estimated(estimator: TipPoseEstimator, images: list[np.ndarray]) -> np.ndarray:
    """Estimated poses (n, 3) of ``images``, nan rows where invalid."""
    estimates = [estimator.estimate(image) for image in images]
    return np.array([e.pose if e.valid else [np.nan] * 3 for e in estimates])


def p95_mm(poses: np.ndarray, truth: np.ndarray) -> float | None:
    error = np.hypot(*(poses[:, :2] - truth[:, :2]).T)
    error = error[np.isfinite(error)]
    return float(np.percentile(error, 95) * 1e3) if error.size else None


def after_reference(estimator: TipPoseEstimator, images: list[np.ndarray], truth: np.ndarray,
                    calibration_images: list[np.ndarray]) -> float | None:
    """p95 [mm] of ``images`` once the tool correction fitted at the Table 10 poses (their
    ``calibration_images``; the true tip as the reference) is applied; None if too few of
    them measure."""
    targets = np.array([t.pose for t in TABLE_10])
    measured = estimated(estimator, calibration_images)
    pairs = {tuple(t): (m, t) for m, t in zip(measured, targets) if np.all(np.isfinite(m))}
    try:
        correction = calibrate_against_reference(targets, lambda t: pairs.get(tuple(t))).correction
    except ValueError:
        return None
    poses = estimated(estimator, images)
    corrected = np.array([correction.pose(p) if np.all(np.isfinite(p)) else p for p in poses])
    return p95_mm(corrected, truth)


def camera_calibrated(estimator: TipPoseEstimator, calibration_images: list[np.ndarray]
                      ) -> TipPoseEstimator | None:
    """The estimator with the camera correction the Table 10 images give (``flexarm
    calibrate --camera``); None if they cannot give one."""
    targets = [t.pose for t in TABLE_10]
    views = [(estimator.match(image), target[2])
             for image, target in zip(calibration_images, targets)]
    views = [(v, angle) for v, angle in views if not isinstance(v, Estimate)]
    try:
        found = calibrate_camera(estimator.camera, [v for v, _ in views],
                                 [angle for _, angle in views])
    except ValueError:
        return None
    camera = estimator.camera
    return estimator.with_camera(camera.with_intrinsics(found.correction.apply(
        camera.intrinsics)))


def run_case(config: dict[str, Any], sources: dict[str, Any], which: tuple[str, ...],
             scale: float, truth: np.ndarray, seed: int) -> dict[str, Any]:
    renderer = true_renderer(config, scaled_errors(sources, which, scale))
    estimator = TipPoseEstimator.from_dict(config)
    rng = np.random.default_rng(seed)
    images = [renderer.render(pose, rng=rng) for pose in truth]
    calibration_images = [renderer.render(t.pose, rng=rng) for t in TABLE_10]
    poses = estimated(estimator, images)
    case: dict[str, Any] = {'errors': list(which), 'scale': scale,
                            'valid_fraction': float(np.isfinite(poses[:, 0]).mean()),
                            'before_mm': p95_mm(poses, truth),
                            'after_reference_mm': after_reference(estimator, images, truth,
                                                                  calibration_images),
                            'after_mm': None, 'after_valid_fraction': None}
    calibrated = camera_calibrated(estimator, calibration_images)
    if calibrated is not None:
        case['after_valid_fraction'] = float(np.isfinite(
            estimated(calibrated, images)[:, 0]).mean())
        case['after_mm'] = after_reference(calibrated, images, truth, calibration_images)
    return case


def worst(cases: list[dict[str, Any]]) -> dict[str, Any]:
    """The smallest valid fractions and the largest errors of ``cases`` (None where a case
    has none)."""
    def pick(key: str, choose: Any) -> float | None:
        values = [c[key] for c in cases]
        return None if any(v is None for v in values) else choose(values)
    return {'valid_fraction': pick('valid_fraction', min),
            'after_valid_fraction': pick('after_valid_fraction', min),
            'before_mm': pick('before_mm', max),
            'after_reference_mm': pick('after_reference_mm', max),
            'after_mm': pick('after_mm', max)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--poses', type=int, default=40)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--scales', default=','.join(map(str, SCALES)))
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    cv2.setNumThreads(1)
    config = {**load_config('camera.yaml'),
              **load_config('vision.yaml', node_name='flexarm_vision')}
    sources = load_config('sim.yaml', node_name='flexarm_sim')['error_sources']
    rng = np.random.default_rng(args.seed)
    truth = np.column_stack([rng.uniform(*X_RANGE, args.poses), rng.uniform(*Y_RANGE, args.poses),
                             rng.uniform(*PHI_RANGE, args.poses)])
    cases = []
    for scale in (float(s) for s in args.scales.split(',')):
        for which in [(name,) for name in ERRORS] + [ERRORS]:
            case = run_case(config, sources, which, scale, truth, args.seed)
            cases.append(case)
            show = {k: (None if v is None else round(v, 3)) for k, v in case.items()
                    if k.endswith('_mm')}
            print(f"{scale:g}x {'+'.join(which):48s} valid {case['valid_fraction']:.3f} "
                  f"{show}", flush=True)
    result = {'poses': args.poses, 'cases': cases,
              'worst': worst([c for c in cases if c['scale'] <= 5]),
              'worst_10x': (worst([c for c in cases if c['scale'] == 10])
                            if any(c['scale'] == 10 for c in cases) else None)}
    print(f"up to 5x: valid fraction {result['worst']['valid_fraction']:.3f}, p95 before "
          f"{result['worst']['before_mm']} mm, after the reference calibration "
          f"{result['worst']['after_reference_mm']} mm, after calibrate --camera "
          f"{result['worst']['after_mm']} mm")
    if args.json:
        print(json.dumps(result))


if __name__ == '__main__':
    main()
