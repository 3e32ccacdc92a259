"""The words `flexarm` says are true: every command line a hint or help suggests parses, every
option it names exists, the defaults its help names are the configured ones, each command's
--domain-id says which graph it means, and move results promise only what the mode promises.
Pure: no ROS graph."""
import argparse
import ast
import importlib.util
import math
import re
from collections.abc import Iterator

import pytest

import flexarm_cli as cli
from flexarm_cli import arguments, common, motion
from flexarm_core.params import load_config
from flexarm_msgs.action import MoveToPose
from flexarm_recording.results.outcome_text import (
    COLLECT_HINTS,
    EXIT_MEANINGS,
    MOVE_HINTS,
    TRAIN_HINT,
    busy_text,
)

PARSER = cli.build_parser()
SUBPARSERS: dict[str, argparse.ArgumentParser] = next(
    a for a in PARSER._actions if isinstance(a, argparse._SubParsersAction)).choices


def _with_actions(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    """A command's parser and those of its actions (bag info, bag export: each its own)."""
    actions = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return [parser, *(sub for a in actions for sub in a.choices.values())]


# modules whose messages reach the operator through `flexarm`
CLI = ('arguments', 'common', 'experiments', 'graph', 'learning', 'motion', 'site')
SPEAKING = ['flexarm_cli', *(f'flexarm_cli.{m}' for m in CLI),
            'flexarm_recording.results.outcome_text', 'flexarm_bringup.graph_status',
            'flexarm_control.ros.client', 'flexarm_deflection.model_store',
            'flexarm_deflection.model_health', 'flexarm_control.ros.compensator_node',
            'flexarm_control.ros.learner_node', 'flexarm_bridge.link_auth']
# A mention of `flexarm COMMAND` is read as a command line to type: up to the end of its
# clause (; , ) ` & '. ' or the line's end).
COMMAND_LINE = re.compile(rf'\bflexarm ((?:{"|".join(SUBPARSERS)})\b[^;,)`&\n]*)')
OPTION = re.compile(r'(?<![\w-])--[a-z][a-z-]*')
PLACEHOLDERS = {'N': '5', 'KG': '2.5', 'NS': 'arm1', 'FILE': 'site.key', 'PATH': 'site.key',
                'NAME': 'x', 'VERSION': '3', '{}': 'x'}


def _literals(module: str) -> Iterator[tuple[str | None, str]]:
    """(command, text) of every string literal of ``module`` but docstrings; an f-string's
    values as '{}'; command: X inside ``cmd_X`` of the CLI, else None."""
    tree = ast.parse(open(importlib.util.find_spec(module).origin, encoding='utf-8').read())
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.JoinedStr):
            skip.update(id(v) for v in node.values)
        body = getattr(node, 'body', None)
        if (isinstance(body, list) and body and isinstance(body[0], ast.Expr)
                and isinstance(body[0].value, ast.Constant)):
            skip.add(id(body[0].value))

    def visit(node: ast.AST, command: str | None) -> Iterator[tuple[str | None, str]]:
        if isinstance(node, ast.FunctionDef) and node.name.startswith('cmd_'):
            command = node.name.removeprefix('cmd_')
        if id(node) not in skip:
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                yield command, node.value
            elif isinstance(node, ast.JoinedStr):
                yield command, ''.join(v.value if isinstance(v, ast.Constant) else '{}'
                                       for v in node.values)
        for child in ast.iter_child_nodes(node):
            yield from visit(child, command)

    yield from visit(tree, None)


def _texts() -> list[tuple[str | None, str]]:
    """Every hint and help text, with the command it belongs to (None: any)."""
    texts = ([('move', t) for t in MOVE_HINTS.values()]
             + [('collect', t) for t in COLLECT_HINTS.values()]
             + [('train', TRAIN_HINT), (None, busy_text('/move_to_pose'))]
             + [(None, t) for t in EXIT_MEANINGS.values()]
             + [(name, a.help) for name, p in SUBPARSERS.items() for sub in _with_actions(p)
                for a in sub._actions if a.help]
             + [(None, a.help) for a in PARSER._actions if a.help])
    return texts + [literal for module in SPEAKING for literal in _literals(module)]


TEXTS = _texts()
COMMAND_LINES = sorted({line.split('. ')[0].strip(' .') for _, text in TEXTS
                        for line in COMMAND_LINE.findall(text)})
OPTIONS = sorted({(command, option) for command, text in TEXTS
                  for option in OPTION.findall(COMMAND_LINE.sub('', text))}, key=str)


def _argv(line: str) -> list[str]:
    """A suggested command line with its placeholders (N, <name>, an f-string's value: a word
    of its own, or nothing when glued to another) replaced by valid values."""
    words = [re.sub(r'^<\w+>$', 'x', word) for word in line.split()]
    return [PLACEHOLDERS.get(word) or word.replace('{}', '') for word in words]


def test_the_texts_suggest_command_lines_and_options():
    assert {'cancel', 'collect 40 --region A --dataset A', 'train --dataset A',
            'collect -h'} <= set(COMMAND_LINES)
    assert ('move', '--max-corrections') in OPTIONS and ('collect', '--strategy') in OPTIONS


@pytest.mark.parametrize('line', COMMAND_LINES)
def test_every_suggested_command_line_parses(line, capsys):
    try:
        PARSER.parse_args(_argv(line))
    except SystemExit as exc:           # -h: 0; a usage error: 2, said on stderr
        assert exc.code == 0, f'`flexarm {line}`: {capsys.readouterr().err}'


@pytest.mark.parametrize('command, option', OPTIONS, ids=[f'{c} {o}' for c, o in OPTIONS])
def test_every_option_named_exists_on_its_command(command, option):
    parsers = (_with_actions(SUBPARSERS[command]) if command
               else [PARSER, *(p for s in SUBPARSERS.values() for p in _with_actions(s))])
    assert any(option in p._option_string_actions for p in parsers), (
        f'{option} is no option of flexarm {command or "any command"}')


def test_help_names_the_learners_defaults_and_every_kind(capsys):
    from flexarm_deflection.models import KINDS

    learner = load_config('learner.yaml', node_name='flexarm_learner')
    assert all(re.search(rf'\b{kind}\b', arguments.KIND_HELP) for kind in KINDS)
    for argv in (['train', '--help'], ['demo', '--help']):
        assert cli.main(argv) == 0
        out = ' '.join(capsys.readouterr().out.split())
        assert f"default: the learner's, {learner['default_kind']}" in out, out
    assert cli.main(['collect', '--help']) == 0
    out = ' '.join(capsys.readouterr().out.split())
    for name in ('region', 'strategy', 'dataset'):
        assert f"default: the learner's, {learner[f'default_{name}']})" in out


def test_domain_id_says_whether_the_command_starts_a_graph_or_joins_one():
    starting = {'up', 'demo', 'benchmark'}           # they start a graph of their own
    for name, parser in SUBPARSERS.items():
        action = parser._option_string_actions.get('--domain-id')
        if action is None:
            continue
        expected = 'to start the graph in' if name in starting else 'of the running graph'
        assert expected in action.help, (name, action.help)
    assert 'of the running graph' in SUBPARSERS['status']._option_string_actions[
        '--domain-id'].help


def test_goal_feedback_is_progress_on_stderr(capsys):
    motion._show_feedback(MoveToPose.Feedback(iteration=1, phase='moving'))
    captured = capsys.readouterr()
    assert captured.err == '  [1] moving\n' and captured.out == ''


def _result(**fields) -> MoveToPose.Result:
    result = MoveToPose.Result(error_code=MoveToPose.Result.SUCCESSFUL, iterations=1,
                               measured=True, position_error=0.023,
                               angle_error=math.radians(0.1))
    result.measured_pose.x, result.measured_pose.y = 1.45, -0.15
    for name, value in fields.items():
        setattr(result, name, value)
    return result


def test_a_rigid_move_is_said_uncompensated_not_reached():
    text = motion._move_text(_result(position_error_bound=0.016, angle_error_bound=0.07))
    assert text.startswith('moved (uncompensated) in 1 move(s): measured x=1450.00 mm'), text
    assert 'error 23.000 mm, 0.1000 deg' in text and 'reached' not in text
    assert motion._move_text(_result(measured=False)).startswith(
        'moved (uncompensated) in 1 move(s), not measured; expected within')


@pytest.mark.parametrize('fields', [
    {'mode_run': MoveToPose.Goal.MODE_CLOSED_LOOP},                   # CLOSED_LOOP, no model
    {'mode_run': MoveToPose.Goal.MODE_CLOSED_LOOP, 'iterations': 3},  # CLOSED_LOOP corrected
    {'mode_run': MoveToPose.Goal.MODE_PREDICTIVE, 'model_version': '4',
     'compensation_iterations': 3}])
def test_a_compensated_move_is_reached(fields):
    text = motion._move_text(_result(**fields))
    assert text.startswith('reached in '), text
    assert motion._move_text(_result(measured=False, **fields)).startswith('moved in ')


def test_the_plans_bound_is_said_beside_the_error():
    text = motion._move_text(_result(mode_run=MoveToPose.Goal.MODE_PREDICTIVE,
                                     position_error_bound=7e-5,
                                     angle_error_bound=math.radians(0.002)))
    assert 'error 23.000 mm, 0.1000 deg' in text
    assert 'expected within 0.070 mm, 0.0020 deg (95 %)' in text
    unknown = motion._move_text(_result(position_error_bound=math.nan,
                                        angle_error_bound=math.nan))
    assert 'no error bound stated' in unknown


@pytest.mark.parametrize('std, says', [(0.0, None), (1e-4, ', model std 0.100 mm')])
def test_the_model_std_is_said_only_where_the_model_gives_one(std, says):
    moved = motion._move_text(_result(model_version='4', compensation_iterations=3,
                                   data_distance=0.8, prediction_std=std))
    planned = motion._move_text(_result(model_version='4', iterations=0, measured=False,
                                     data_distance=0.8, prediction_std=std))
    for text in (moved, planned):
        assert '0.80 sample spacings from the learned data' in text, text
        assert ('model std' in text) == (says is not None)
        assert says is None or says in text
    assert planned.startswith('plan (model v4; nothing moved)')


def test_the_help_builds_where_config_is_not_beside_the_code(monkeypatch):
    """An install space (colcon) holds the code without config/: --help must still work."""
    def missing() -> None:
        raise FileNotFoundError('config/learner.yaml')
    monkeypatch.setattr(common, 'learner_settings', missing)
    train = cli.build_parser()._subparsers._group_actions[0].choices['train']
    text = ' '.join(train.format_help().split())
    assert "(default: the learner's, its default_kind parameter)" in text
