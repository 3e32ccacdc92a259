"""The measurement file a site brings: one row per pose, read against the arm's URDF.

CSV with a header: one column per actuated joint of the chain, named as in the URDF [rad or
m]; ``x, y, z`` [m]: the measured target in the instrument's frame; optional ``qx, qy, qz,
qw`` (the target's measured orientation in the instrument's frame, a unit quaternion: all four
or none; normalised, a zero one skips its row), ``payload`` [kg],
``temperature`` [°C] and ``group`` (rows measured together: they stay together in every
split). Any other column is an error, as is a missing joint: a misspelt name must not
silently drop a joint. Rows with an empty, NaN or infinite value (or an empty ``group``) are
skipped and counted; joint values outside the URDF's limits are kept and counted (the URDF's
limits may be conservative).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from flexarm_learning.urdf_arm import UrdfArm

POINT = ('x', 'y', 'z')
ORIENTATION = ('qx', 'qy', 'qz', 'qw')
OPTIONAL = ORIENTATION + ('payload', 'temperature', 'group')


class MeasurementError(ValueError):
    """The measurement file cannot be read against this URDF; the message says why."""


@dataclass(frozen=True)
class Measurements:
    """Rows of joints (N, n) in the URDF's chain order and measured points (N, 3) [m]."""

    joints: np.ndarray
    points: np.ndarray
    payload: np.ndarray          # (N,) [kg], zeros where the file has none
    group: np.ndarray            # (N,) a label per row; each row its own without the column
    skipped: int = 0             # rows with a missing, NaN or infinite value or no group
    outside_limits: int = 0      # rows with a joint outside the URDF's limits
    rotations: np.ndarray | None = None   # (N, 3, 3) measured orientations, where given

    def __len__(self) -> int:
        return len(self.joints)

    def subset(self, rows: np.ndarray) -> Measurements:
        return Measurements(self.joints[rows], self.points[rows], self.payload[rows],
                            self.group[rows], rotations=None if self.rotations is None
                            else self.rotations[rows])


def read_csv(path: str | Path, arm: UrdfArm) -> Measurements:
    """The file's rows, checked against ``arm`` (module docstring); MeasurementError else."""
    path = Path(path)
    try:
        with path.open(newline='', encoding='utf-8') as f:
            reader = csv.reader(f)
            header = [h.strip() for h in next(reader, [])]
            rows = list(reader)
    except OSError as e:
        raise MeasurementError(f'cannot read {path}: {e.strerror}') from None
    except UnicodeDecodeError:
        raise MeasurementError(f'{path} is not a UTF-8 text file') from None
    return parse(header, rows, arm, str(path))


def parse(header: list[str], rows: list[list[str]], arm: UrdfArm,
          source: str = 'the measurements') -> Measurements:
    """:func:`read_csv` of a header and rows already split (blank lines are not rows; the
    messages count lines as a text editor does, the header line 1)."""
    known = set(arm.joint_names) | set(POINT) | set(OPTIONAL)
    unknown = [h for h in header if h not in known]
    if unknown:
        raise MeasurementError(
            f'{source}: column(s) {unknown} are neither joints of the URDF '
            f'({", ".join(arm.joint_names)}) nor one of {", ".join(POINT + OPTIONAL)}')
    missing = [h for h in arm.joint_names + POINT if h not in header]
    if missing:
        raise MeasurementError(f'{source}: missing column(s) {missing} (the URDF chain to '
                               f'{arm.tip!r} has joints {", ".join(arm.joint_names)})')
    if len(set(header)) != len(header):
        raise MeasurementError(f'{source}: a column appears twice in {header}')
    quaternion = [h for h in ORIENTATION if h in header]
    if quaternion and len(quaternion) != len(ORIENTATION):
        raise MeasurementError(f'{source}: an orientation needs all of {", ".join(ORIENTATION)};'
                               f' the file has only {", ".join(quaternion)}')
    numeric = [h for h in header if h != 'group']
    lines = [(line, row) for line, row in enumerate(rows, start=2)
             if any(cell.strip() for cell in row)]
    rows = [row for _, row in lines]
    values = np.full((len(rows), len(numeric)), np.nan)
    for r, (line, row) in enumerate(lines):
        if len(row) != len(header):
            raise MeasurementError(f'{source}: line {line} has {len(row)} values, the header '
                                   f'{len(header)}')
        for c, name in enumerate(numeric):
            try:
                values[r, c] = float(row[header.index(name)])
            except ValueError:
                if row[header.index(name)].strip():
                    raise MeasurementError(f'{source}: line {line}, column {name!r}: '
                                           f'{row[header.index(name)]!r} is not a number'
                                           ) from None
    good = np.isfinite(values).all(axis=1)
    if quaternion:
        q = values[:, [numeric.index(h) for h in ORIENTATION]]
        good &= np.linalg.norm(np.nan_to_num(q), axis=1) > 0
    if 'group' in header:
        labels = np.array([row[header.index('group')].strip() for row in rows], dtype=object)
        good &= labels != ''
        groups = labels[good]
    else:
        groups = np.arange(int(good.sum())).astype(str).astype(object)
    column = {name: values[good, c] for c, name in enumerate(numeric)}
    joints = np.stack([column[j] for j in arm.joint_names], axis=1)
    outside = (joints < arm.lower) | (joints > arm.upper)
    rotations = None
    if quaternion:
        rotations = Rotation.from_quat(np.stack([column[h] for h in ORIENTATION], axis=1)
                                       ).as_matrix()
    return Measurements(
        joints=joints, points=np.stack([column[c] for c in POINT], axis=1),
        payload=column.get('payload', np.zeros(len(joints))), group=groups,
        skipped=int((~good).sum()), outside_limits=int(outside.any(axis=1).sum()),
        rotations=rotations)
