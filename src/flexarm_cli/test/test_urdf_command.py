"""`flexarm urdf [FILE]`: the robot description without a graph, to stdout or to a file
written atomically, that ROS's URDF parser reads (tests/test_visibility.py: it is what the
state publisher of a running graph publishes)."""
from __future__ import annotations

from pathlib import Path

from urdf_parser_py.urdf import URDF

from flexarm_cli import main
from flexarm_recording.results.outcome_text import Exit


def test_urdf_goes_to_stdout_or_to_a_file_that_ros_parses(tmp_path: Path, capsys) -> None:
    assert main(['urdf']) == Exit.OK
    printed = capsys.readouterr().out
    path = tmp_path / 'robot' / 'flexarm.urdf'
    assert main(['urdf', str(path)]) == Exit.OK
    assert f'written to {path}' in capsys.readouterr().out
    assert path.read_text() == printed
    assert [p.name for p in path.parent.iterdir()] == ['flexarm.urdf']     # no temporary left
    robot = URDF.from_xml_string(printed)
    assert [j.name for j in robot.joints][:4] == ['joint1', 'joint2', 'joint3', 'joint4']


def test_an_unknown_robot_is_a_usage_error(capsys) -> None:
    assert main(['urdf', '--robot', 'nope']) == Exit.USAGE
    assert "unknown robot 'nope'" in capsys.readouterr().err
