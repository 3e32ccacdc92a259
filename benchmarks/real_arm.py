"""Accuracy on real measurements: a UR10 and a laser tracker, flexarm's learning core beside
the plain reference, trained on N rows and judged on all the others.

Data: ../shared/data/ipa-robot-accuracy (Landgraf, Ernst, Schleth, Fabritius, Huber: *A Hybrid
Neural Network Approach for Increasing the Absolute Accuracy of Industrial Robots*, IEEE CASE
2021; MIT licence), turned into flexarm's CSV contract (docs/accuracy.md: decimal commas read,
mm to m) and read back through it, as a site's file would be. Robot: the UR10's published
nominal kinematics and inertials (benchmarks/data/ur10), the target on ``tool0``.

Ours: the default kind of ``flexarm accuracy`` (registration, geometry, compliances, learned
joint errors; its 95 % radius calibrated on the training rows). The reference, the plain way:
registration only (instrument frame and target offset) and a scikit-learn GP on the residual
(RBF with a length scale per joint + white noise, one GP per axis, 3 optimiser restarts),
fitted on the same rows of the same splits. Figures are held-out means over the splits. The
tracker's orientation of the probe (``measurement_rx, ry, rz``, intrinsic x-y-z Euler angles)
goes into the contract as a quaternion: ``angle_mean_mrad`` is the angle between the
orientation ours predicts and the measured one.

Through the night (series A; its timestamps run from 2020-07-14 16:39 to 07-18 21:27 with
gaps of up to 21 h, 22.9-23.7 °C): learn on the first hour, then every later row in the order
it was measured is a goal; the share within the online radius (``coverage_overnight``,
updated from each measured error) beside the radius fixed at the fit
(``coverage_overnight_fixed``), and each one's median radius over the median error. The
series sweeps its 619 goal positions (each at ~22 orientations) through time: the first
hour's poses hardly recur, so this is as much a move into unseen poses as a drift.

    python benchmarks/real_arm.py [--series C] [--others A,B,D] [--sizes 40,200] [--splits 3]
                                  [--data DIR] [--json]

Smoke run: --series D --others A --sizes 20 --splits 1
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import tempfile
import time
import warnings
from datetime import datetime
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_limits

from flexarm_learning.accuracy_study import evaluate, split
from flexarm_learning.arm_error import ArmErrorModel
from flexarm_learning.choices import DEFAULT_KIND
from flexarm_learning.elastostatic import ElastostaticModel
from flexarm_learning.measurements import Measurements, read_csv
from flexarm_learning.online_radius import OnlineRadius
from flexarm_learning.urdf_arm import UrdfArm

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / 'shared' / 'data' / 'ipa-robot-accuracy'
URDF, TIP = REPO / 'benchmarks' / 'data' / 'ur10' / 'ur10.urdf', 'tool0'
SERIES = {'A': 'Series_A/measurements_grid.csv',
          'B': 'Series_B/measurements_joint_configurations.csv',
          'C': 'Series_C/measurements_random_poses.csv',
          'D': 'Series_D/measurements_iso_cubes.csv'}
# the tracker's rx, ry, rz [deg]: intrinsic x-y-z Euler angles (the one of the usual six
# sequences whose rotations a rigid fit meets to 0.07 degrees on series C; the others leave
# 5-12 degrees)
EULER = 'XYZ'
JOINTS = ('shoulder_pan_joint', 'shoulder_lift_joint', 'elbow_joint', 'wrist_1_joint',
          'wrist_2_joint', 'wrist_3_joint')


def to_contract(source: Path, target: Path) -> np.ndarray:
    """The dataset's file (';', decimal commas, mm) as flexarm's CSV contract (',', m), its
    rows in the order they were measured; their times [s] from the first (NaN where the file's
    timestamps are rounded beyond use: series B-D)."""
    with source.open(newline='', encoding='utf-8') as f:
        rows = [row for row in csv.reader(f, delimiter=';') if row]
    header = [h.strip() for h in rows[0]]
    column = {name: header.index(name) for name in header}

    def number(row: list[str], name: str) -> float:
        return float(row[column[name]].replace(',', '.'))

    stamps = [row[column['Timestamp']].strip() for row in rows[1:]]
    if all(s.isdigit() and len(s) == 14 for s in stamps):       # yyyymmddHHMMSS (series A)
        times = np.array([datetime.strptime(s, '%Y%m%d%H%M%S').timestamp() for s in stamps])
        times -= times.min()
    else:
        times = np.full(len(stamps), np.nan)
    order = np.argsort(np.nan_to_num(times), kind='stable')
    with target.open('w', newline='', encoding='utf-8') as f:
        out = csv.writer(f)
        out.writerow([*JOINTS, 'x', 'y', 'z', 'qx', 'qy', 'qz', 'qw', 'temperature'])
        for k in order:
            row = rows[k + 1]
            turn = Rotation.from_euler(EULER, [number(row, f'measurement_r{a}') for a in 'xyz'],
                                       degrees=True)
            out.writerow([*(number(row, j) for j in JOINTS),
                          *(number(row, f'measurement_{a}') / 1000 for a in 'xyz'),
                          *turn.as_quat(), number(row, 'measurement_temperature')])
    return times[order]


def overnight(arm: UrdfArm, data: Measurements, times: np.ndarray) -> dict[str, float]:
    """Learn on the first hour (every other row of it), then go through the night in the
    order it was measured, each row a goal: the online radius (:mod:`flexarm_learning.
    online_radius`) updated from each one's measured error, beside the radius fixed at the
    fit; coverage over the night and the mean error per hour."""
    first = np.flatnonzero(times < 3600.0)
    model = ArmErrorModel(arm, DEFAULT_KIND).fit(data.subset(first[::2]))
    night = np.flatnonzero(times >= 3600.0)
    points, spread = model.predict_spread(data.joints[night], data.payload[night])
    error = np.linalg.norm(points - data.points[night], axis=1)
    online = OnlineRadius(model.scores)
    radius, covered = np.empty(len(error)), np.empty(len(error), bool)
    for k, (e, s) in enumerate(zip(error, spread)):
        radius[k] = online.factor * s
        covered[k] = online.update(e, s)
    hour = (times[night] // 3600).astype(int)
    return {'coverage_overnight': float(covered.mean()),
            'coverage_overnight_fixed': float(np.mean(error <= model.factor * spread)),
            'sharpness_overnight': float(np.median(radius) / np.median(error)),
            'sharpness_overnight_fixed': float(np.median(model.factor * spread)
                                               / np.median(error)),
            'overnight_mean_mm': 1e3 * float(error.mean()),
            'overnight_train_rows': len(first[::2]), 'overnight_rows': len(night),
            'overnight_hours': float(times.max() / 3600),
            'overnight_mean_mm_by_hour': [1e3 * float(error[hour == h].mean())
                                          for h in np.unique(hour)]}


def reference(arm: UrdfArm, data: Measurements, train: int, seed: int) -> dict[str, float]:
    """Registration and a scikit-learn GP on the residual, on the split ``evaluate`` uses."""
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

    mask = split(data.group, train, seed)
    start = time.perf_counter()
    rigid = ElastostaticModel(arm, compliance=False, geometry=False).fit(
        data.joints[mask], data.points[mask])
    left = data.points[mask] - rigid.predict(data.joints[mask])
    mean, std = data.joints[mask].mean(axis=0), data.joints[mask].std(axis=0) + 1e-12
    kernel = (ConstantKernel(1.0, (1e-3, 1e3)) * RBF(np.ones(arm.dof), (1e-2, 1e3))
              + WhiteKernel(1e-2, (1e-6, 1.0)))
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', ConvergenceWarning)
        gps = [GaussianProcessRegressor(kernel, n_restarts_optimizer=3, normalize_y=True,
                                        random_state=seed).fit((data.joints[mask] - mean) / std,
                                                               left[:, k]) for k in range(3)]
    fit_s = time.perf_counter() - start
    held = ~mask
    base = rigid.predict(data.joints[held])
    learned = np.stack([gp.predict((data.joints[held] - mean) / std) for gp in gps], axis=1)
    error = np.linalg.norm(base + learned - data.points[held], axis=1)
    return {'rigid_mean_mm': 1e3 * np.linalg.norm(base - data.points[held], axis=1).mean(),
            'mean_mm': 1e3 * error.mean(), 'max_mm': 1e3 * error.max(), 'fit_s': fit_s}


def series_figures(arm: UrdfArm, data: Measurements, sizes: list[int], splits: int,
                   ) -> dict[str, dict[str, float]]:
    """Per training size: ours and the reference, means over the splits."""
    out = {}
    for size in sizes:
        ours = [evaluate(arm, data, DEFAULT_KIND, size, seed) for seed in range(splits)]
        ref = [reference(arm, data, size, seed) for seed in range(splits)]

        def mean(runs: list[dict[str, float]], key: str) -> float:
            return float(np.mean([r[key] for r in runs]))

        out[str(size)] = {
            'rigid_mean_mm': mean(ref, 'rigid_mean_mm'), 'mean_mm': 1e3 * mean(ours, 'mean_m'),
            'rms_mm': 1e3 * mean(ours, 'rms_m'), 'max_mm': 1e3 * mean(ours, 'max_m'),
            'bound_coverage': mean(ours, 'coverage'), 'sharpness': mean(ours, 'sharpness'),
            'fit_s': mean(ours, 'fit_s'), 'reference_mean_mm': mean(ref, 'mean_mm'),
            'reference_max_mm': mean(ref, 'max_mm'), 'reference_fit_s': mean(ref, 'fit_s'),
            'ratio': 1e3 * mean(ours, 'mean_m') / mean(ref, 'mean_mm'),
            'angle_mean_mrad': 1e3 * mean(ours, 'angle_mean_rad'),
            'angle_max_mrad': 1e3 * mean(ours, 'angle_max_rad'),
            'held_out_rows': len(data) - int(split(data.group, size, 0).sum())}
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--series', default='C', choices=sorted(SERIES),
                        help='the series whose figures are the headline keys')
    parser.add_argument('--others', default='A,B,D', help="series printed beside ('' none)")
    parser.add_argument('--sizes', default='40,200', help='training rows, comma-separated')
    parser.add_argument('--splits', type=int, default=3, help='random splits per size')
    parser.add_argument('--data', type=Path, default=DATA, help='the dataset folder')
    parser.add_argument('--no-overnight', dest='overnight', action='store_false',
                        help='skip series A through the night (with A among the series)')
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    if not args.data.is_dir():
        parser.error(f'no dataset at {args.data} (the shared UR10 measurements; --data DIR)')
    threadpool_limits(1)
    sizes = [int(s) for s in args.sizes.split(',')]
    arm = UrdfArm.from_file(URDF, TIP)
    names = [args.series] + [s for s in args.others.split(',') if s and s != args.series]
    result: dict = {'robot': 'UR10', 'kind': DEFAULT_KIND, 'splits': args.splits,
                    'series': {}}
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            contract = Path(tmp) / f'series_{name}.csv'
            times = to_contract(args.data / SERIES[name], contract)
            data = read_csv(contract, arm)
            figures = series_figures(arm, data, sizes, args.splits)
            result['series'][name] = {'rows': len(data), 'sizes': figures}
            if name == 'A' and args.overnight:
                night = overnight(arm, data, times)
                result |= night
                print(f"series A through the night: coverage {night['coverage_overnight']:.3f} "
                      f"online, {night['coverage_overnight_fixed']:.3f} fixed", file=sys.stderr,
                      flush=True)
            for size, f in figures.items():
                print(f"series {name}, {size} rows: rigid {f['rigid_mean_mm']:.3f} mm, "
                          f"ours {f['mean_mm']:.3f} mm (max {f['max_mm']:.3f}, coverage "
                      f"{f['bound_coverage']:.3f}, sharpness {f['sharpness']:.2f}, fit "
                      f"{f['fit_s']:.1f} s), reference {f['reference_mean_mm']:.3f} mm, "
                      f"ratio {f['ratio']:.2f}; angle {f['angle_mean_mrad']:.3f} mrad (max "
                      f"{f['angle_max_mrad']:.2f})", file=sys.stderr, flush=True)
    head = result['series'][args.series]['sizes']
    for size, f in head.items():
        result |= {f'mean_mm_{size}': f['mean_mm'], f'rigid_mean_mm_{size}': f['rigid_mean_mm'],
                   f'coverage_{size}': f['bound_coverage'],
                   f'sharpness_{size}': f['sharpness'], f'fit_s_{size}': f['fit_s'],
                   f'reference_mean_mm_{size}': f['reference_mean_mm'],
                   f'ratio_{size}': f['ratio'], f'angle_mean_mrad_{size}': f['angle_mean_mrad']}
    print(json.dumps(result) if args.json else json.dumps(result, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
