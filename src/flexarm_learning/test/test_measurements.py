"""The measurement file read against the arm's URDF (read_csv, parse), the study's size check
and its grouped split: every refusal names what is wrong (a column, a row, a link)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from synthetic_arms import TIP, seven_joint_arm, seven_joint_names

from flexarm_learning.accuracy_study import MIN_TRAIN, StudyError, check_size, evaluate, split
from flexarm_learning.measurements import MeasurementError, Measurements, parse, read_csv
from flexarm_learning.urdf_arm import DescriptionError, UrdfArm

REPO = Path(__file__).resolve().parents[3]
UR10 = REPO / 'benchmarks' / 'data' / 'ur10' / 'ur10.urdf'
NAMES = seven_joint_names()
POINT = ('x', 'y', 'z')
ROW = ['0.1', '-0.2', '0.3', '-0.4', '0.5', '-0.6', '0.7', '1.25', '-0.5', '0.75']  # 7 q, x y z


@pytest.fixture(scope='module')
def arm() -> UrdfArm:
    return UrdfArm.from_xml(seven_joint_arm(), TIP)


def write_csv(path: Path, header: list[str] | tuple[str, ...], rows: list[list[str]]) -> Path:
    path.write_text('\n'.join(','.join(cells) for cells in [list(header), *rows]) + '\n',
                    encoding='utf-8')
    return path


def header(*extra: str) -> list[str]:
    return [*NAMES, *POINT, *extra]


def measurements(rows: int, group: np.ndarray | None = None) -> Measurements:
    rng = np.random.default_rng(0)
    return Measurements(rng.uniform(-1.0, 1.0, (rows, 7)), rng.normal(size=(rows, 3)),
                        np.zeros(rows), np.arange(rows).astype(str).astype(object)
                        if group is None else group)


def test_a_well_formed_file_is_read_in_the_urdfs_chain_order(arm: UrdfArm,
                                                               tmp_path: Path) -> None:
    """Columns in any order, the optional ones included: joints come back in the chain's
    order, points in metres, payload and group per row; nothing skipped or outside."""
    order = ['z', *reversed(NAMES), 'group', 'payload', 'x', 'y']
    rows = []
    for k in range(3):
        values = dict(zip([*NAMES, *POINT], ROW)) | {'z': str(k), 'group': f'g{k // 2}',
                                                     'payload': str(1.5 * k)}
        rows.append([values[name] for name in order])
    data = read_csv(write_csv(tmp_path / 'm.csv', order, rows), arm)
    assert len(data) == 3 and data.skipped == 0 and data.outside_limits == 0
    np.testing.assert_array_equal(data.joints, np.tile(np.array(ROW[:7], float), (3, 1)))
    np.testing.assert_array_equal(data.points[:, 2], [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(data.points[:, :2], [[1.25, -0.5]] * 3)
    np.testing.assert_array_equal(data.payload, [0.0, 1.5, 3.0])
    assert list(data.group) == ['g0', 'g0', 'g1']


def test_an_unknown_column_is_named_with_the_urdfs_joints(arm: UrdfArm,
                                                           tmp_path: Path) -> None:
    """A misspelt joint ('elbw') is refused, not read as an extra column: the message names
    it and lists the joints the URDF has."""
    columns = [name if name != 'elbow' else 'elbw' for name in NAMES] + list(POINT)
    with pytest.raises(MeasurementError) as error:
        read_csv(write_csv(tmp_path / 'm.csv', columns, [ROW]), arm)
    message = str(error.value)
    assert "'elbw'" in message
    assert all(name in message for name in NAMES)


def test_an_unknown_column_of_a_real_urdf_lists_its_joints(tmp_path: Path) -> None:
    """The UR10's joints end in '_joint': a file with the short names is refused with the
    URDF's names in the message."""
    ur10 = UrdfArm.from_file(UR10, 'tool0')
    short = [name.removesuffix('_joint') for name in ur10.joint_names]
    with pytest.raises(MeasurementError) as error:
        parse([*short, *POINT], [ROW[:6] + ROW[7:]], ur10, 'ur10.csv')
    message = str(error.value)
    assert message.startswith('ur10.csv: ')
    assert "'shoulder_pan'" in message
    assert all(name in message for name in ur10.joint_names)


def test_a_missing_joint_column_is_named(arm: UrdfArm, tmp_path: Path) -> None:
    columns = [name for name in header() if name != 'wrist_pitch']
    row = [value for name, value in zip(header(), ROW) if name != 'wrist_pitch']
    with pytest.raises(MeasurementError) as error:
        read_csv(write_csv(tmp_path / 'm.csv', columns, [row]), arm)
    message = str(error.value)
    assert 'missing' in message and "'wrist_pitch'" in message


def test_a_missing_point_column_is_named(arm: UrdfArm) -> None:
    with pytest.raises(MeasurementError, match=r"missing column\(s\) \['z'\]"):
        parse([*NAMES, 'x', 'y'], [ROW[:9]], arm)


def test_rows_with_an_empty_or_nan_value_are_skipped_and_counted(arm: UrdfArm,
                                                                  tmp_path: Path) -> None:
    """An empty cell, 'nan' and 'NaN', in a joint, a point or the payload: those rows are
    left out and counted; the others are kept in order. Wholly blank lines are no rows."""
    columns = header('payload')
    good = [[*ROW[:9], str(k), '0.5'] for k in range(3)]
    empty_joint = ['', *ROW[1:], '0.5']
    nan_point = [*ROW[:8], 'nan', ROW[9], '0.5']
    nan_payload = [*ROW, 'NaN']
    rows = [good[0], empty_joint, good[1], nan_point, nan_payload, good[2]]
    path = write_csv(tmp_path / 'm.csv', columns, rows)
    path.write_text(path.read_text() + '\n,,,,,,,,,,\n')
    data = read_csv(path, arm)
    assert data.skipped == 3
    assert len(data) == 3
    np.testing.assert_array_equal(data.points[:, 2], [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(data.payload, [0.5, 0.5, 0.5])
    assert len(data.group) == 3 and len(set(data.group)) == 3   # each row its own group


def test_a_joint_outside_the_urdfs_limits_is_kept_and_counted(arm: UrdfArm,
                                                               tmp_path: Path) -> None:
    """The elbow's limit is ±2.0 rad: a row at 2.5 rad is read (the URDF may be cautious) and
    counted; the continuous wrist roll has no limit to be outside of."""
    beyond = list(ROW)
    beyond[NAMES.index('elbow')] = '2.5'
    turned = list(ROW)
    turned[NAMES.index('wrist_roll')] = '12.0'
    data = read_csv(write_csv(tmp_path / 'm.csv', header(), [ROW, beyond, turned]), arm)
    assert len(data) == 3 and data.skipped == 0
    assert data.outside_limits == 1
    assert data.joints[1, NAMES.index('elbow')] == 2.5


def test_a_cell_that_is_not_a_number_names_its_line_and_column(arm: UrdfArm,
                                                                tmp_path: Path) -> None:
    """The header is the file's line 1, and blank lines count as an editor counts them:
    after a row and a blank line the bad row is line 4."""
    bad = list(ROW)
    bad[POINT.index('y') + 7] = '12mm'
    with pytest.raises(MeasurementError) as error:
        read_csv(write_csv(tmp_path / 'm.csv', header(), [ROW, [], bad]), arm)
    message = str(error.value)
    assert 'line 4' in message and "'y'" in message and "'12mm'" in message
    assert 'not a number' in message


def test_a_row_of_the_wrong_length_is_named(arm: UrdfArm) -> None:
    with pytest.raises(MeasurementError, match='line 2 has 9 values, the header 10'):
        parse(header(), [ROW[:9]], arm)


@pytest.mark.parametrize('what', ['missing', 'folder', 'binary'])
def test_an_unreadable_file_is_a_measurement_error(arm: UrdfArm, tmp_path: Path,
                                                   what: str) -> None:
    path = tmp_path / 'm.csv'
    if what == 'folder':
        path.mkdir()
    elif what == 'binary':
        path.write_bytes(b'\xff\xfe\x00\x81' * 16)
    with pytest.raises(MeasurementError) as error:
        read_csv(path, arm)
    assert str(path) in str(error.value)


def test_a_tip_link_not_in_the_urdf_is_named(tmp_path: Path) -> None:
    """From XML and from a file (the synthetic arm's and the UR10's): the message names the
    link asked for and the links there are."""
    with pytest.raises(DescriptionError) as error:
        UrdfArm.from_xml(seven_joint_arm(), 'tol')
    assert "'tol'" in str(error.value) and TIP in str(error.value)
    path = tmp_path / 'seven.urdf'
    path.write_text(seven_joint_arm())
    with pytest.raises(DescriptionError, match=f"'flange' is not in {path}"):
        UrdfArm.from_file(path, 'flange')
    with pytest.raises(DescriptionError) as error:
        UrdfArm.from_file(UR10, 'tool')
    assert "'tool'" in str(error.value) and 'tool0' in str(error.value)


def test_check_size_refuses_fewer_training_rows_than_parameters() -> None:
    data = measurements(30)
    for train in range(1, MIN_TRAIN):
        with pytest.raises(StudyError, match='fewer rows than parameters'):
            check_size(data, train)
    check_size(data, MIN_TRAIN)


def test_check_size_refuses_training_on_every_row() -> None:
    data = measurements(20)
    for train in (20, 21, 100):
        with pytest.raises(StudyError, match=f'--train {train} leaves none of the 20'):
            check_size(data, train)
    check_size(data, 19)


@pytest.mark.parametrize('seed', [0, 1, 2, 7])
def test_split_keeps_each_group_on_one_side(seed: int) -> None:
    """Groups of 1-5 rows, shuffled through the file: every group is wholly in training or
    wholly held out, training has at least ``train`` rows and keeps some back, and a seed
    gives one split."""
    rng = np.random.default_rng(seed)
    sizes = rng.integers(1, 6, 40)
    group = np.repeat([f'g{k}' for k in range(len(sizes))], sizes).astype(object)
    group = group[rng.permutation(len(group))]
    for train in (MIN_TRAIN, 10, 25, len(group) // 2):
        mask = split(group, train, seed)
        for label in np.unique(group):
            sides = set(mask[group == label])
            assert len(sides) == 1, f'group {label} straddles the split (train {train})'
        assert train <= mask.sum() < len(group)
        np.testing.assert_array_equal(mask, split(group, train, seed))


def test_split_of_singletons_takes_exactly_train_rows() -> None:
    group = np.arange(50).astype(str).astype(object)
    masks = [split(group, 20, seed) for seed in range(3)]
    assert all(mask.sum() == 20 for mask in masks)
    assert not np.array_equal(masks[0], masks[1])     # seeds differ



def test_an_infinite_value_or_an_empty_group_skips_its_row(arm: UrdfArm,
                                                          tmp_path: Path) -> None:
    """'inf' is no measurement, and a row without its group cannot be kept apart: both are
    left out and counted like a missing value."""
    rows = [[*ROW, 'a'], [*ROW[:7], 'inf', *ROW[8:], 'a'], [*ROW, ''], [*ROW, 'b']]
    data = read_csv(write_csv(tmp_path / 'm.csv', header('group'), rows), arm)
    assert (len(data), data.skipped) == (2, 2)
    assert list(data.group) == ['a', 'b']


def test_a_tip_that_is_a_joint_not_a_link_is_refused() -> None:
    """A frame that is a joint's (here the elbow's) is no link to fix a target to."""
    joint = seven_joint_names()[3]
    with pytest.raises(DescriptionError, match=f"'{joint}' is not in"):
        UrdfArm.from_xml(seven_joint_arm(), joint)


def test_groups_that_take_every_row_leave_nothing_to_judge(arm: UrdfArm) -> None:
    """Two groups of ten and 11 training rows: whole groups take all 20; the study says so
    instead of judging on no row."""
    data = measurements(20, np.repeat(np.array(['a', 'b'], dtype=object), 10))
    data = Measurements(np.zeros((20, 7)), data.points, data.payload, data.group)
    check_size(data, 11)
    with pytest.raises(StudyError, match='none is left to judge'):
        evaluate(arm, data, 'rigid', 11, seed=0)


def test_an_orientation_is_read_as_rotations_and_a_zero_one_skips_its_row(
        arm: UrdfArm, tmp_path: Path) -> None:
    """qx, qy, qz, qw (any scale) become rotation matrices, scipy's order; a quaternion of
    zeros is no orientation: its row is skipped and counted."""
    turn = Rotation.from_rotvec([0.1, -0.2, 0.3])
    quaternion = [str(v) for v in 2.0 * turn.as_quat()]
    rows = [[*ROW, *quaternion], [*ROW, '0', '0', '0', '0'], [*ROW, *quaternion]]
    data = read_csv(write_csv(tmp_path / 'm.csv', header('qx', 'qy', 'qz', 'qw'), rows), arm)
    assert (len(data), data.skipped) == (2, 1)
    np.testing.assert_allclose(data.rotations, [turn.as_matrix()] * 2, atol=1e-12)
    assert read_csv(write_csv(tmp_path / 'n.csv', header(), [ROW]), arm).rotations is None


def test_part_of_an_orientation_is_refused(arm: UrdfArm) -> None:
    with pytest.raises(MeasurementError, match='needs all of qx, qy, qz, qw'):
        parse(header('qx', 'qy', 'qz'), [[*ROW, '0', '0', '0']], arm)
