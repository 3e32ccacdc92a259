"""Parameter files: ROS 2 params format read without rclpy."""
from pathlib import Path

import pytest

from flexarm_core.params import load_node_params, unflatten


def test_node_section_overrides_wildcard(tmp_path: Path) -> None:
    path = tmp_path / 'p.yaml'
    path.write_text(
        '/**:\n  ros__parameters:\n    arm: {a: 1, b: {c: 2, d: 3}}\n'
        'node:\n  ros__parameters:\n    arm: {b: {c: 20}}\n    rate: 5.0\n')
    assert load_node_params(path, 'node') == {'arm': {'a': 1, 'b': {'c': 20, 'd': 3}},
                                              'rate': 5.0}
    assert load_node_params(path, 'other') == {'arm': {'a': 1, 'b': {'c': 2, 'd': 3}}}


def test_unflatten_nests_dotted_names() -> None:
    flat = {'plant.mass.arm2': 4.81, 'plant.payload': 5.0, 'rate': [1, 2]}
    assert unflatten(flat) == {'plant': {'mass': {'arm2': 4.81}, 'payload': 5.0},
                               'rate': [1, 2]}


@pytest.mark.parametrize('name', ['arm.yaml', 'sim.yaml', 'camera.yaml', 'vision.yaml',
                                  'learner.yaml', 'compensator.yaml', 'motion.yaml',
                                  'recorder.yaml'])
def test_shipped_config_files_are_ros_params_files(name: str) -> None:
    import yaml

    from flexarm_core.params import config_path

    doc = yaml.safe_load(config_path(name).read_text())
    assert doc, f'{name} is empty'
    for section in doc.values():
        assert set(section) == {'ros__parameters'}, f'{name}: bad section keys {set(section)}'
