"""The packages form layers: each imports only packages below it, and its package.xml and
pyproject.toml declare exactly the flexarm packages it imports (and every ROS package)."""
from __future__ import annotations

import ast
import re
import tomllib
from pathlib import Path
from xml.etree import ElementTree

import pytest

SRC = Path(__file__).resolve().parents[1] / 'src'
# Lowest first: a package may import only the ones before it.
LAYERS = ['flexarm_msgs', 'flexarm_core', 'flexarm_description', 'flexarm_vision',
          'flexarm_bridge', 'flexarm_sim', 'flexarm_control', 'flexarm_bringup']
ROS = {'rclpy', 'std_msgs', 'sensor_msgs', 'geometry_msgs', 'rosgraph_msgs', 'builtin_interfaces',
       'action_msgs', 'unique_identifier_msgs', 'rcl_interfaces', 'diagnostic_msgs',
       'visualization_msgs', 'tf2_msgs', 'control_msgs'}


def imported(package: str) -> set[str]:
    """Top-level names the package's modules (not its tests) import."""
    names: set[str] = set()
    for path in (SRC / package / package).rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.Import):
                names.update(alias.name.split('.')[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split('.')[0])
    return names


def exec_depends(package: str) -> set[str]:
    root = ElementTree.parse(SRC / package / 'package.xml').getroot()
    return {e.text for e in root.iter('exec_depend')}


def project_depends(package: str) -> set[str]:
    with open(SRC / package / 'pyproject.toml', 'rb') as f:
        deps = tomllib.load(f)['project']['dependencies']
    return {re.split(r'[<>=\[ ]', d)[0].replace('-', '_') for d in deps}


@pytest.mark.parametrize('package', LAYERS[1:])
def test_a_package_imports_only_the_layers_below_it_and_declares_them(package):
    below = set(LAYERS[:LAYERS.index(package)])
    ours = {n for n in imported(package) if n.startswith('flexarm_')} - {package}
    assert ours <= below, f'{package} imports {sorted(ours - below)} from its own layer or above'
    assert {d for d in exec_depends(package) if d.startswith('flexarm_')} == ours
    assert project_depends(package) == ours
    missing = (imported(package) & ROS) - exec_depends(package)
    assert not missing, f'{package}/package.xml lacks {sorted(missing)}'


def test_every_package_is_in_a_layer():
    assert {p.name for p in SRC.iterdir() if (p / 'package.xml').exists()} == set(LAYERS)


def test_only_the_simulator_reads_its_truth():
    """config/sim.yaml defines the simulated real arm: no other package's code names it (the
    control side reads the nominal robot description, config/arm.yaml)."""
    readers = set()
    for package in LAYERS[1:]:
        for path in (SRC / package / package).rglob('*.py'):
            for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
                if isinstance(node, ast.Constant) and node.value in ('sim.yaml',
                                                                      'config/sim.yaml'):
                    readers.add(package)
    assert readers == {'flexarm_sim'}


def test_in_the_controller_only_its_ros_shell_imports_rclpy():
    """flexarm_control's learning and execution are pure: the nodes, the arm interface and the
    client (``flexarm_control/ros``) are its only modules that import rclpy."""
    package = SRC / 'flexarm_control' / 'flexarm_control'
    shell = {path.relative_to(package).parts[0] for path in package.rglob('*.py')
             if _imports_rclpy(path)}
    assert shell == {'ros'}


def _imports_rclpy(path: Path) -> bool:
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
        if isinstance(node, ast.Import) and any(a.name.split('.')[0] == 'rclpy'
                                                 for a in node.names):
            return True
        if isinstance(node, ast.ImportFrom) and (node.module or '').split('.')[0] == 'rclpy':
            return True
    return False
