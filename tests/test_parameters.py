"""A parameter is written once: in the shipped params file that is its schema (its value the
default, its comment the description, unit and range: flexarm_core.parameter_schema). No code
passes a default, so nothing can disagree with the file (a default that had drifted from its
file, e.g. the learner's default kind, went unseen); every parameter of the shipped files says
what it is, and every range holds its default."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
import yaml

from flexarm_core.parameter_schema import file_schema
from flexarm_core.params import config_path

SRC = Path(__file__).resolve().parents[1] / 'src'
DECLARER = Path('flexarm_core/flexarm_core/ros/node_params.py')    # under src/
SOURCE = re.compile(r'config/[\w.-]+\.yaml')
# flexarm's declarations: their positional arguments (node, name, source and what may follow
# it) and the keywords they take; none takes a value
OURS = {'declare': (4, {'read_only'}), 'declare_tree': (4, {'dynamic'})}
RCLPY = {'declare_parameter', 'declare_parameters', 'get_parameter_or'}


def called(call: ast.Call) -> str:
    """The name of the function or method a call calls ('' for another callee)."""
    func = call.func
    return func.id if isinstance(func, ast.Name) else func.attr if isinstance(
        func, ast.Attribute) else ''


def offences(text: str, module: Path) -> list[str]:
    """``line: why`` of every call of ``text`` that writes a parameter's default in code: a
    declaration given a value (its source not a ``config/<file>.yaml``, more arguments than a
    source and the writable names, a keyword of its own), or rclpy's declaring calls outside
    :mod:`flexarm_core.ros.node_params`."""
    found = []
    for node in ast.walk(ast.parse(text)):
        if not isinstance(node, ast.Call):
            continue
        name = called(node)
        if name in RCLPY and module != DECLARER:
            found.append(f'{node.lineno}: {name}, only {DECLARER} declares with rclpy')
        elif name in OURS:
            most, keywords = OURS[name]
            source = node.args[2] if len(node.args) > 2 else None
            if not (isinstance(source, ast.Constant) and isinstance(source.value, str)
                    and SOURCE.fullmatch(source.value)):
                found.append(f'{node.lineno}: {name} without a config/<file>.yaml source')
            elif len(node.args) > most or {k.arg for k in node.keywords} - keywords:
                found.append(f'{node.lineno}: {name} given more than its source')
    return found


def modules() -> list[Path]:
    return sorted(path.relative_to(SRC) for path in SRC.rglob('*.py')
                  if '.egg-info' not in str(path))


def declared_sources() -> set[str]:
    """The files the declarations under src/ name (``config/<file>.yaml``)."""
    return {node.args[2].value for path in modules()
            for node in ast.walk(ast.parse((SRC / path).read_text(encoding='utf-8')))
            if isinstance(node, ast.Call) and called(node) in OURS and len(node.args) > 2
            and isinstance(node.args[2], ast.Constant)}


def shipped_files() -> list[str]:
    """Every params file config/graph.yaml gives a node, and every one a declaration reads."""
    graph = yaml.safe_load(config_path('graph.yaml').read_text(encoding='utf-8'))
    nodes = [node for group in (*graph['robots'].values(), graph['nodes'], graph['optional'],
                                graph['rehearsal']) for node in group]
    return sorted({name for node in nodes for name in node['params_files']}
                  | {Path(source).name for source in declared_sources()})


def test_no_code_writes_a_parameters_default() -> None:
    found = {str(path): why for path in modules()
             if (why := offences((SRC / path).read_text(encoding='utf-8'), path))}
    assert not found, found


def test_the_scan_finds_a_default_written_in_code() -> None:
    offender = '''
declare(self, 'rate', 25.0, '[Hz] wake-ups', bounds=(0.1, 100.0))
declare(self, 'rate', 'config/sim.yaml', default=25.0)
declare_tree(self, 'arm', 'config/arm.yaml', (), 'more')
self.declare_parameter('lower', [0.0, 1.0])
node.get_parameter_or('rate', 25.0)
declare(self, 'rate', 'config/sim.yaml', read_only=True)
declare_tree(self, 'plant', 'config/sim.yaml', {'payload'})
'''
    assert offences(offender, Path('flexarm_x/flexarm_x/x_node.py')) == [
        '2: declare without a config/<file>.yaml source',
        '3: declare given more than its source',
        '4: declare_tree given more than its source',
        f'5: declare_parameter, only {DECLARER} declares with rclpy',
        f'6: get_parameter_or, only {DECLARER} declares with rclpy']
    assert offences("node.declare_parameter(name, spec.default, described)", DECLARER) == []


def test_the_shipped_files_are_found() -> None:
    assert {'arm.yaml', 'sim.yaml', 'vision.yaml', 'recorder.yaml', 'foxglove.yaml',
            'clock.yaml'} <= set(shipped_files())


@pytest.mark.parametrize('name', shipped_files())
def test_every_parameter_of_a_shipped_file_is_described_within_its_range(name: str) -> None:
    schema = file_schema(config_path(name).read_text(encoding='utf-8'), f'config/{name}')
    specs = [spec for section in schema.values() for spec in section.values()]
    assert specs, f'{name} holds no parameter'
    assert not [spec.name for spec in specs if not spec.description], (
        f'{name}: undescribed parameters (a comment on the line, or directly above)')
    outside = [(spec.name, spec.default, spec.range) for spec in specs if spec.range
               and not spec.range[0] <= spec.default <= spec.range[1]]
    assert not outside, f'{name}: defaults outside their range: {outside}'
