"""How well flexarm would compensate an arm, from how many measurements, and whether its
bounds hold: every kind fitted on ``train`` rows, judged on the rows it did not learn from.

Splits are random but grouped (rows of one ``group`` stay on one side) and seeded: split k of
seed s is the same for every kind, so kinds compare row for row. Figures are the means over
the splits of: the 3-D error's mean, RMS, 95th percentile and maximum [mm] on the held-out
rows; ``coverage``, the share of held-out rows within their stated 95 % radius; ``sharpness``,
the median radius over the median error (1 would be a bound as tight as the error itself;
the 95 % radius of a well-modelled 3-D Gaussian error is about 1.8); ``fit_s``, the wall time
of a fit with its radius' calibration. The learning curve repeats the default kind's mean
error over training sizes.
"""
from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from flexarm_learning.arm_error import DEFAULT_KIND, ArmErrorModel
from flexarm_learning.elastostatic import REGISTRATION
from flexarm_learning.measurements import Measurements
from flexarm_learning.urdf_arm import UrdfArm

LEARNING_CURVE = (10, 20, 40, 80, 160)
MIN_TRAIN = REGISTRATION // 3 + 1     # rows: more coordinates (3 a row) than free unknowns


class StudyError(ValueError):
    """The study cannot be run as asked; the message says why."""


def split(group: np.ndarray, train: int, seed: int) -> np.ndarray:
    """A mask of at least ``train`` training rows, whole groups in a seeded random order."""
    labels, counts = np.unique(group, return_counts=True)
    order = np.random.default_rng(seed).permutation(len(labels))
    taken = order[:np.searchsorted(np.cumsum(counts[order]), train) + 1]
    return np.isin(group, labels[taken])


def check_size(data: Measurements, train: int) -> None:
    if train < MIN_TRAIN:
        raise StudyError(
            f'fewer rows than parameters: {train} training rows give {3 * train} coordinates '
            f'for the {REGISTRATION} unknowns of the registration alone (instrument frame and '
            f'target offset); train on at least {MIN_TRAIN} rows')
    if train >= len(data):
        raise StudyError(f'--train {train} leaves none of the {len(data)} usable rows to judge '
                         'the model on')


def evaluate(arm: UrdfArm, data: Measurements, kind: str, train: int, seed: int,
             ) -> dict[str, float]:
    """One kind on one split (figures of the module docstring)."""
    mask = split(data.group, train, seed)
    if mask.all():
        raise StudyError(f'{train} training rows in whole groups take all {len(data)} rows: '
                         'none is left to judge the model on (fewer rows, or smaller groups)')
    start = time.perf_counter()
    model = ArmErrorModel(arm, kind).fit(data.subset(mask), seed=seed)
    fit_s = time.perf_counter() - start
    held = data.subset(~mask)
    points, radius = model.predict(held.joints, held.payload)
    error = np.linalg.norm(points - held.points, axis=1)
    return {'mean_mm': 1e3 * error.mean(), 'rms_mm': 1e3 * np.sqrt(np.mean(error ** 2)),
            'p95_mm': 1e3 * np.quantile(error, 0.95), 'max_mm': 1e3 * error.max(),
            'coverage': float(np.mean(error <= radius)),
            'sharpness': float(np.median(radius) / np.median(error)), 'fit_s': fit_s,
            'bound_median_mm': 1e3 * float(np.median(radius))}


def study(arm: UrdfArm, data: Measurements, train: int, splits: int = 3, seed: int = 0,
          kinds: Sequence[str] = (DEFAULT_KIND,),
          curve: Sequence[int] = LEARNING_CURVE) -> dict:
    """Every kind (and the rigid model after registration) on ``splits`` splits; the
    learning curve of the first kind."""
    check_size(data, train)
    seeds = [seed + k for k in range(splits)]

    def mean_of(kind: str, size: int) -> dict[str, float]:
        runs = [evaluate(arm, data, kind, size, s) for s in seeds]
        return {key: float(np.mean([r[key] for r in runs])) for key in runs[0]}

    report = {
        'rows': len(data), 'skipped_rows': data.skipped,
        'rows_outside_limits': data.outside_limits, 'joints': list(arm.joint_names),
        'tip': arm.tip, 'train': train, 'splits': splits, 'seed': seed,
        'gravity': ArmErrorModel(arm, kinds[0]).gravity,
        'rigid': mean_of('rigid', train),
        'kinds': {kind: mean_of(kind, train) for kind in kinds},
        'curve': [{'train': size, **mean_of(kinds[0], size)} for size in curve
                  if MIN_TRAIN <= size < len(data)],
    }
    fitted = ArmErrorModel(arm, kinds[0]).fit(data.subset(split(data.group, train, seed)))
    report['registration'] = {
        'target_offset_mm': (1e3 * fitted.physics.offset).round(3).tolist(),
        'target_offset_std_mm': (1e3 * fitted.physics.registration_std[6:9]).round(3).tolist(),
        'target_distance_mm': round(1e3 * float(np.linalg.norm(fitted.physics.offset)), 3),
        'physics_residual_mm': round(1e3 * fitted.physics.noise, 4)}
    return report
