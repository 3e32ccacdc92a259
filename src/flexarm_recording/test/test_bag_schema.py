"""ros2msg schema text assembled from the installed .msg files, in rosbag2's format."""
from pathlib import Path

import pytest

from flexarm_recording.bag_schema import (
    SEPARATOR,
    field_dependencies,
    find_msg_file,
    message_definition,
    split_type_name,
)


def _sections(text: str) -> dict[str, str]:
    """Dependency name -> its text, split at rosbag2's separator lines."""
    parts = text.split(f'\n{SEPARATOR}\n')
    return {part.split('\n', 1)[0].removeprefix('MSG: '): part.split('\n', 1)[1]
            for part in parts[1:]}


def test_image_schema_has_header_and_time_sections_once() -> None:
    text = message_definition('sensor_msgs/msg/Image')
    assert text.startswith(find_msg_file('sensor_msgs/msg/Image').read_text())
    sections = _sections(text)
    assert list(sections) == ['std_msgs/Header', 'builtin_interfaces/Time']
    assert 'builtin_interfaces/Time stamp' in sections['std_msgs/Header']
    assert 'uint32 nanosec' in sections['builtin_interfaces/Time']
    assert text.count('MSG: builtin_interfaces/Time\n') == 1


def test_package_relative_types_resolve_to_own_package() -> None:
    sections = _sections(message_definition('flexarm_msgs/msg/TipPose'))
    assert set(sections) == {'std_msgs/Header', 'builtin_interfaces/Time',
                             'flexarm_msgs/PlanarPose'}


def test_field_dependencies_skip_primitives_arrays_constants_and_comments() -> None:
    text = ('# geometry_msgs/Point commented out\n'
            'uint8 MODE_RIGID=0\n'
            'float64[4] joints  # [rad]\n'
            'string<=10 name\n'
            'PlanarPose[] poses\n'
            'geometry_msgs/Point[<=3] points\n'
            'builtin_interfaces/Time stamp\n')
    assert field_dependencies(text, 'flexarm_msgs') == [
        'builtin_interfaces/Time', 'flexarm_msgs/PlanarPose', 'geometry_msgs/Point']


def test_type_names_and_missing_files_are_reported(tmp_path: Path) -> None:
    assert split_type_name('std_msgs/msg/Header') == ('std_msgs', 'Header')
    assert split_type_name('std_msgs/Header') == ('std_msgs', 'Header')
    with pytest.raises(ValueError):
        split_type_name('Header')
    with pytest.raises(FileNotFoundError, match='std_msgs/msg/Header.msg'):
        find_msg_file('std_msgs/msg/Header', prefixes=[tmp_path])
    (tmp_path / 'share' / 'std_msgs' / 'msg').mkdir(parents=True)
    (tmp_path / 'share' / 'std_msgs' / 'msg' / 'Header.msg').write_text('string frame_id\n')
    assert find_msg_file('std_msgs/msg/Header', prefixes=[tmp_path]) \
        == tmp_path / 'share' / 'std_msgs' / 'msg' / 'Header.msg'
