"""How well flexarm would compensate an arm, from how many measurements, and whether its
bounds hold: every kind fitted on ``train`` rows, judged on the rows it did not learn from.

Splits are random but grouped (rows of one ``group`` stay on one side) and seeded: split k of
seed s is the same for every kind, so kinds compare row for row. Figures are the means over
the splits of: the 3-D error's mean, RMS, 95th percentile and maximum [m] on the held-out
rows (SI, as every result below the command line, which shows mm); ``coverage``, the share
of held-out rows within their stated 95 % radius; ``sharpness``, the median radius over the
median error (1 would be a bound as tight as the error itself; the 95 % radius of a
well-modelled 3-D Gaussian error is about 1.8); ``fit_s``, the wall time of a fit with its
radius' calibration; where the orientation is measured, the angle between the predicted and
the measured orientation, mean and maximum [rad]. The learning curve repeats the default
kind's mean error over training sizes.
"""
from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from flexarm_learning.arm_error import ArmErrorModel
from flexarm_learning.choices import DEFAULT_KIND, LEARNING_CURVE, SPLITS
from flexarm_learning.measurements import Measurements
from flexarm_learning.urdf_arm import UrdfArm

REGISTRATION = 9      # unknowns of the instrument's frame (6) and the target's offset (3)
MIN_TRAIN = REGISTRATION // 3 + 1     # rows: more coordinates (3 a row) than those unknowns


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
    return fit_and_judge(arm, data, kind, train, seed)[0]


def fit_and_judge(arm: UrdfArm, data: Measurements, kind: str, train: int, seed: int,
                  ) -> tuple[dict[str, float], ArmErrorModel]:
    """:func:`evaluate`'s figures and the model fitted."""
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
    figures = {'mean_m': float(error.mean()), 'rms_m': float(np.sqrt(np.mean(error ** 2))),
               'p95_m': float(np.quantile(error, 0.95)), 'max_m': float(error.max()),
               'coverage': float(np.mean(error <= radius)),
               'sharpness': float(np.median(radius) / np.median(error)), 'fit_s': fit_s,
               'bound_median_m': float(np.median(radius))}
    if held.rotations is not None:
        turned = Rotation.from_matrix(model.rotations(held.joints, held.payload)
                                      @ np.swapaxes(held.rotations, 1, 2)).magnitude()
        figures.update(angle_mean_rad=float(turned.mean()), angle_max_rad=float(turned.max()))
    return figures, model


def study(arm: UrdfArm, data: Measurements, train: int, splits: int = SPLITS, seed: int = 0,
          kinds: Sequence[str] = (DEFAULT_KIND,),
          curve: Sequence[int] = LEARNING_CURVE) -> dict:
    """Every kind (and the rigid model after registration) on ``splits`` splits; the
    learning curve of the first kind."""
    check_size(data, train)
    seeds = [seed + k for k in range(splits)]

    def mean_of(kind: str, size: int) -> tuple[dict[str, float], list[ArmErrorModel]]:
        """The figures' means over the splits, and the model of each split."""
        judged = [fit_and_judge(arm, data, kind, size, s) for s in seeds]
        return ({key: float(np.mean([f[key] for f, _ in judged])) for key in judged[0][0]},
                [model for _, model in judged])

    by_kind = {kind: mean_of(kind, train) for kind in kinds}
    physics = by_kind[kinds[0]][1][0].physics
    report = {
        'rows': len(data), 'skipped_rows': data.skipped,
        'rows_outside_limits': data.outside_limits, 'joints': list(arm.joint_names),
        'tip': arm.tip, 'train': train, 'splits': splits, 'seed': seed,
        'gravity': physics.gravity,
        'rigid': mean_of('rigid', train)[0],
        'kinds': {kind: figures for kind, (figures, _) in by_kind.items()},
        'chosen': {kind: [model.chosen for model in models]          # auto's, per split
                   for kind, (_, models) in by_kind.items() if kind == 'auto'},
        'curve': [{'train': size, **mean_of(kinds[0], size)[0]} for size in curve
                  if MIN_TRAIN <= size < len(data) and not split(data.group, size, seed).all()],
    }
    report['registration'] = {
        'target_offset_m': physics.offset.tolist(),
        'target_offset_std_m': physics.registration_std[6:9].tolist(),
        'target_distance_m': float(np.linalg.norm(physics.offset)),
        'physics_residual_m': physics.noise}
    return report
