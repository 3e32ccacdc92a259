"""A node's parameters are defined once: where a node declares a parameter with a default in
code and the config files config/graph.yaml gives it set the same parameter, the two agree, so
that a node started without its files behaves as the shipped graph does (a default that had
drifted from its file, e.g. the learner's default kind, went unseen)."""
from __future__ import annotations

import ast
import importlib.util
import math
from pathlib import Path
from typing import Any

import pytest
import yaml

from flexarm_core.params import config_path, flatten, load_node_params

GRAPH = yaml.safe_load(config_path('graph.yaml').read_text(encoding='utf-8'))
NODES = [n for group in (*GRAPH['robots'].values(), GRAPH['nodes'], GRAPH['optional'])
         for n in group]


def declarations(module: str) -> dict[str, tuple[Any, Any]]:
    """``declare(self, 'name', <default>, ..., bounds=...)`` calls of a node module: name:
    (default, bounds), each None where the code computes it at run time."""
    path = Path(importlib.util.find_spec(module).origin)
    found: dict[str, tuple[Any, Any]] = {}
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
        if (isinstance(node, ast.Call) and getattr(node.func, 'id', '') == 'declare'
                and len(node.args) >= 3 and isinstance(node.args[1], ast.Constant)):
            bounds = next((k.value for k in node.keywords if k.arg == 'bounds'), None)
            found[node.args[1].value] = (_literal(node.args[2]), _literal(bounds))
    return found


def _literal(node: ast.AST | None) -> Any:
    try:
        return None if node is None else ast.literal_eval(node)
    except ValueError:
        return None


def declared_defaults(module: str) -> dict[str, Any]:
    return {name: default for name, (default, _) in declarations(module).items()
            if default is not None}


def shipped(node: dict[str, Any]) -> dict[str, Any]:
    values: dict[str, Any] = {}
    for name in node.get('params_files', []):
        values.update(flatten(load_node_params(config_path(name), node['name'])))
    return values


def same(a: Any, b: Any) -> bool:
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return math.isclose(a, b, rel_tol=1e-12, abs_tol=0.0)
    return a == b


@pytest.mark.parametrize('node', NODES, ids=lambda n: n['name'])
def test_a_code_default_agrees_with_the_shipped_file(node: dict[str, Any]) -> None:
    code, files = declared_defaults(node['module']), shipped(node)
    differ = {name: (value, files[name]) for name, value in code.items()
              if name in files and not same(value, files[name])}
    assert not differ, f"{node['name']}: code default vs its config files: {differ}"


def test_the_check_sees_the_nodes_declarations() -> None:
    learner = next(n for n in NODES if n['name'] == 'flexarm_learner')
    assert declared_defaults(learner['module'])['default_kind'] == shipped(learner)[
        'default_kind'] == 'auto'


@pytest.mark.parametrize('node', NODES, ids=lambda n: n['name'])
def test_defaults_and_shipped_values_lie_within_the_declared_bounds(node: dict[str, Any]
                                                                    ) -> None:
    files = shipped(node)
    for name, (default, bounds) in declarations(node['module']).items():
        if bounds is None:
            continue
        low, high = bounds
        for value in (default, files.get(name, default)):
            assert value is None or low <= value <= high, (node['name'], name, value, bounds)
