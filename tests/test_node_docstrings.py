"""Docstrings that orient: a node's module opens with its role in at most 15 lines (the
predictor interface 20) and links to the docs section that explains the rest, whose page and
anchor exist; and no docstring in src/ states its own length, which goes stale with the first
edit."""
from __future__ import annotations

import ast
import importlib.util
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / 'src'
MAX_LINES = 15
LONGER = {'src/flexarm_deflection/flexarm_deflection/predictors/base.py': 20}
NOT_NAMED_NODE = ['src/flexarm_sim/flexarm_sim/fake_controller.py',
                  'src/flexarm_deflection/flexarm_deflection/predictors/base.py']
DOCS_LINK = re.compile(r'\bdocs/([\w./-]+\.md)#([\w-]+)')
OWN_LENGTH = re.compile(r'~\s*\d+\s+lines')


def _anchors():
    """tests/test_docs.py's ``anchors``: a page's heading anchors as mkdocs makes them."""
    spec = importlib.util.spec_from_file_location('docs_checks', REPO / 'tests/test_docs.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.anchors


anchors = _anchors()


def documented_modules() -> list[str]:
    """Every node module of src/ (``*_node.py`` outside the packages' tests) and the other
    modules held to the same opening, as repository paths."""
    nodes = {path.relative_to(REPO).as_posix() for path in SRC.glob('*/*/**/*_node.py')
             if 'test' not in path.relative_to(SRC).parts}
    return sorted(nodes | set(NOT_NAMED_NODE))


def test_the_documented_modules_are_found() -> None:
    modules = documented_modules()
    for module in ('src/flexarm_control/flexarm_control/ros/learner_node.py',
                   'src/flexarm_motion/flexarm_motion/ros/arm_owner_node.py',
                   'src/flexarm_sim/flexarm_sim/sim_node.py',
                   'src/flexarm_control/flexarm_control/ros/compensator_node.py',
                   *NOT_NAMED_NODE):
        assert module in modules
    assert not any('/test/' in module for module in modules)


@pytest.mark.parametrize('module', documented_modules())
def test_a_node_module_opens_with_its_role_and_a_link_to_its_docs(module: str) -> None:
    tree = ast.parse((REPO / module).read_text(encoding='utf-8'))
    docstring = ast.get_docstring(tree, clean=False)
    assert docstring, f'{module} has no module docstring'
    opening = tree.body[0]
    lines = opening.end_lineno - opening.lineno + 1     # as the file shows it, quotes included
    limit = LONGER.get(module, MAX_LINES)
    assert lines <= limit, f'{module}: a module docstring of {lines} lines (at most {limit})'
    links = DOCS_LINK.findall(docstring)
    assert links, f'{module}: its module docstring links to no docs/PAGE.md#section'
    for page, anchor in links:
        target = REPO / 'docs' / page
        assert target.is_file(), f'{module} links to docs/{page}: no such page'
        assert anchor in anchors(target), (f'{module} links to docs/{page}#{anchor}: '
                                           'no such section')


def stating_their_length() -> dict[str, list[str]]:
    """The files of src/ with a docstring (module, class or function) that states its own
    length ("~570 lines"), with those docstrings' first lines."""
    found: dict[str, list[str]] = {}
    for path in sorted(SRC.rglob('*.py')):
        tree = ast.parse(path.read_text(encoding='utf-8'))
        for node in ast.walk(tree):
            if not isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef,
                                     ast.AsyncFunctionDef)):
                continue
            docstring = ast.get_docstring(node, clean=False)
            if docstring and OWN_LENGTH.search(docstring):
                found.setdefault(path.relative_to(REPO).as_posix(), []).append(
                    f'line {getattr(node, "lineno", 1)}: {docstring.splitlines()[0]}')
    return found


def test_no_docstring_in_src_states_its_own_length() -> None:
    found = stating_their_length()
    assert not found, f'docstrings that state their own length: {found}'


def test_the_length_pattern_finds_a_stated_length() -> None:
    assert OWN_LENGTH.search('One module of ~570 lines: the node maps')
    assert OWN_LENGTH.search('about ~ 600 lines')
    assert not OWN_LENGTH.search('the last 570 lines of the log')
