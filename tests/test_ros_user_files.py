"""The files for users of a system ROS install (docs/ros-users.md) hold to the graph:
launch/flexarm.launch.py is what scripts/launch_file.py makes of config/graph.yaml now, and
config/flexarm.rviz shows topics the graph has, in a frame it publishes, with the durability
their publishers offer (a latched subscription to a volatile publisher matches none, and shows
nothing). Read as text: no ROS node is started, and launch/launch_ros need not be installed."""
from __future__ import annotations

import ast
import re
import subprocess
import sys
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import yaml

from flexarm_core import frames, topics

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / 'src'
LAUNCH_FILE = ROOT / 'launch/flexarm.launch.py'
RVIZ = ROOT / 'config/flexarm.rviz'
# rviz display class: the message type it shows (topics.py's comments name the types).
DISPLAY_TYPES = {'rviz_default_plugins/RobotModel': 'std_msgs/String',
                 'rviz_default_plugins/Pose': 'geometry_msgs/PoseStamped',
                 'rviz_default_plugins/MarkerArray': 'visualization_msgs/MarkerArray',
                 'rviz_default_plugins/Image': 'sensor_msgs/Image'}
PUBLISHER = re.compile(r'create_publisher\(\s*\w+,\s*topics\.(\w+),\s*(\w+)')
LATCHED = {'latched', 'LATCHED'}      # the nodes' names of their TRANSIENT_LOCAL profiles


def launch_tables() -> dict[str, Any]:
    """The launch file's literal tables (NODES, GRAPHS), as its module would hold them."""
    tree = ast.parse(LAUNCH_FILE.read_text(encoding='utf-8'))
    return {node.targets[0].id: ast.literal_eval(node.value) for node in tree.body
            if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name)
            and node.targets[0].id in ('NODES', 'GRAPHS')}


def graph_yaml() -> dict[str, Any]:
    return yaml.safe_load((ROOT / 'config/graph.yaml').read_text(encoding='utf-8'))


def test_the_launch_file_is_what_graph_yaml_gives_and_parses_as_python():
    checked = subprocess.run([sys.executable, str(ROOT / 'scripts/launch_file.py'), '--check'],
                             capture_output=True, text=True, timeout=60)
    assert checked.returncode == 0, checked.stderr
    ast.parse(LAUNCH_FILE.read_text(encoding='utf-8'))


def test_the_launch_file_imports_only_launch_and_launch_ros():
    tree = ast.parse(LAUNCH_FILE.read_text(encoding='utf-8'))
    imported = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import)
                for alias in node.names}
    imported |= {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert imported and {name.split('.')[0] for name in imported} <= {'launch', 'launch_ros'}


def test_the_launch_file_starts_every_node_with_its_module_params_files_and_parameters():
    """Every node of every robot entry, of ``nodes`` and of ``optional``: its executable runs
    its module's main(), with its params files and graph.yaml's parameters over them."""
    graph, tables, text = graph_yaml(), launch_tables(), LAUNCH_FILE.read_text(encoding='utf-8')
    assert list(tables['GRAPHS']) == list(graph['robots'])
    for robot, entry in graph['robots'].items():
        settings = graph['robot_settings'][robot]
        specs = [*(entry or ()), *graph['nodes'], *graph['optional']]
        assert list(tables['GRAPHS'][robot]) == [d['name'] for d in specs]
        for d in specs:
            node = tables['NODES'][d['name']]
            assert f"'{d['name']}': {{  # python -m {d['module']}\n" in text
            assert node['params_files'] == d['params_files']
            assert node['restart'] == d['restart']
            scripts = tomllib.loads((SRC / node['package'] / 'pyproject.toml').read_text(
                encoding='utf-8'))['project']['scripts']
            assert scripts[node['executable']] == f"{d['module']}:main"
            wanted = {**{k: settings[k] for k in d.get('robot_parameters', ())},
                      **d.get('parameters', {})}
            assert tables['GRAPHS'][robot][d['name']] == wanted, (robot, d['name'])


def rviz() -> dict[str, Any]:
    return yaml.safe_load(RVIZ.read_text(encoding='utf-8'))


def subscriptions(tree: Any, display: str = '') -> Iterator[tuple[str, str, dict[str, Any]]]:
    """(display class, topic, QoS) of every topic an rviz config names, tools' too."""
    if isinstance(tree, list):
        for item in tree:
            yield from subscriptions(item, display)
    elif isinstance(tree, dict):
        display = tree.get('Class', display)
        for key, value in tree.items():
            if key in ('Topic', 'Description Topic'):
                yield (display, value['Value'], value) if isinstance(value, dict) else (
                    display, value, {})
            else:
                yield from subscriptions(value, display)


def topic_types() -> dict[str, str]:
    """Absolute name: type of every one-line constant of topics.py (the comment's first word)."""
    source = (SRC / 'flexarm_core/flexarm_core/topics.py').read_text(encoding='utf-8')
    return {topics.absolute(name): kind for name, kind in
            re.findall(r"^[A-Z_]+ = '([^']+)' +# ([\w/]+)", source, re.MULTILINE)}


def latched_publishers() -> dict[str, set[bool]]:
    """Absolute topic: whether each of its publishers in the nodes' sources latches."""
    found: dict[str, set[bool]] = {}
    for path in SRC.glob('flexarm_*/flexarm_*/**/*.py'):
        if 'flexarm_test_support' not in path.parts:
            for const, qos in PUBLISHER.findall(path.read_text(encoding='utf-8')):
                found.setdefault(topics.absolute(getattr(topics, const)), set()).add(
                    qos in LATCHED)
    return found


def test_the_rviz_config_names_only_topics_of_the_graph_with_their_types():
    names = {topics.absolute(value) for name, value in vars(topics).items()
             if name.isupper() and isinstance(value, str)}
    shown = list(subscriptions(rviz()))
    assert {topic for _, topic, _ in shown} >= {'/robot_description', '/scene/target_pose',
                                                '/scene/commanded_pose', '/scene/markers'}
    types = topic_types()
    for display, topic, _ in shown:
        assert topic in names, f'{display} shows {topic}, which flexarm_core.topics lacks'
        assert types[topic] == DISPLAY_TYPES[display], (display, topic)


def test_the_rviz_config_asks_for_the_durability_the_publishers_offer():
    """Transient Local exactly where every publisher latches: else rviz matches no publisher
    (latched asked of a volatile one) or misses what was published before it started."""
    latched = latched_publishers()
    assert latched['/robot_description'] == {True} and latched['/joint_states'] == {False}
    for display, topic, qos in subscriptions(rviz()):
        wanted = 'Transient Local' if latched.get(topic) == {True} else 'Volatile'
        assert qos.get('Durability Policy') == wanted, (display, topic)


def test_the_rviz_fixed_frame_is_one_the_graph_publishes():
    published = {value for name, value in vars(frames).items() if name.endswith('_FRAME')}
    assert rviz()['Visualization Manager']['Global Options']['Fixed Frame'] in published
