"""`flexarm` without a graph: bad input is refused before anything connects, in words, with
exit code 2 and no traceback; help shows defaults and only the options a subcommand uses; a
missing graph is named by its ROS domain (exit 3).

Every test runs with ROS_DOMAIN_ID set to an empty domain of its own (``domain_id``): a
command that connected instead of refusing would wait for a graph there and exit 3, not 2.
"""
import json
import signal
import sys
import time
from importlib import metadata
from pathlib import Path

import pytest

from flexarm_cli import arguments, main
from flexarm_recording.results.outcome_text import Exit

pytestmark = pytest.mark.duration(25)

README = str(Path(__file__).resolve().parents[3] / 'README.md')
A1 = ['1450', '-150', '-45']

BAD_INPUT = [
    (['collect', '-5'], 'argument N: must be a whole number > 0'),
    (['collect', '0'], 'argument N: must be a whole number > 0'),
    (['collect', '3000'], 'count must be 1..2000 (max_count of config/learner.yaml)'),
    (['collect', '5', '--region', 'Z'],
     'unknown region "Z"; presets of config/learner.yaml: A, B, AB, paper'),
    (['collect', '5', '--strategy', 'zigzag'], 'unknown strategy "zigzag"'),
    (['collect', '5', '--dataset', '../x'], 'dataset name "../x" must be'),
    (['collect', '5', '--seed', '-1'], 'argument --seed: must be a whole number >= 0'),
    (['train', 'nonsense'], 'unknown predictor kind "nonsense"; known kinds: mlp, rbf, gp'),
    (['train', 'mlp', '--settings', '[10]'], 'argument --settings: must be a JSON object'),
    (['train', '--settings', '{hidden: 10}'], 'argument --settings: not valid JSON'),
    (['train', '--dataset', 'a/b'], 'dataset name "a/b" must be'),
    (['move', '1450', '-150', 'nan'], 'argument phi: must be a finite number'),
    (['move', *A1, '--position-tolerance', '-0.1'], 'must be a number >= 0'),
    (['move', *A1, '--max-corrections', '-1'], 'must be a whole number >= 0'),
    (['move', *A1, '--wait', '0'], 'argument --wait: must be a number > 0'),
    (['move', *A1, '--domain-id', '300'], 'must be a ROS domain 0..232'),
    (['bag', 'info', 'bags/nope'], 'no bag at bags/nope'),
    (['bag', 'export', README], 'README.md is not an MCAP bag'),
    (['bag', 'info', 'bags/nope', '--domain-id', '3'], 'unrecognized arguments: --domain-id'),
    (['bag', 'info', 'bags/nope', '--out', 'x'], 'unrecognized arguments: --out'),
    (['study', '--wait', '3'], 'unrecognized arguments: --wait'),
    (['study', '--region', 'Z'], 'unknown region "Z"'),
    (['study', '--seeds', '0'], 'argument --seeds: must be a whole number > 0'),
    (['demo', '--kind', 'svm'], 'unknown predictor kind "svm"'),
    (['up', '--link-key', '/nonexistent/site.key'], 'no key file /nonexistent/site.key'),
    (['up', '--only', 'sim,camera'],
     'unknown node(s) camera; the graph has sim, arm_owner, vision'),
    (['payload', '-1'], 'argument KG: must be a number >= 0'),
    (['collect', '5', '--payload', 'x'], 'argument --payload: must be a number >= 0'),
    (['refresh', '--region', 'Z'], 'unknown region "Z"'),
]


@pytest.mark.node
@pytest.mark.parametrize('argv, says', BAD_INPUT, ids=[' '.join(a) for a, _ in BAD_INPUT])
def test_bad_input_is_refused_in_words_before_connecting(argv, says, domain_id, capsys):
    handler = signal.getsignal(signal.SIGTERM)
    started = time.monotonic()
    assert main(argv) == Exit.USAGE
    assert time.monotonic() - started < 10          # refused, not waited for a graph
    err = capsys.readouterr().err
    assert says in err and 'Traceback' not in err
    assert signal.getsignal(signal.SIGTERM) is handler    # main restores what it replaced


@pytest.mark.node
def test_up_refuses_a_profiles_file_fast_dds_would_ignore(domain_id, monkeypatch, tmp_path,
                                                          capsys):
    broken = tmp_path / 'dds.xml'
    broken.write_text('<dds><transport_descriptors>')
    monkeypatch.setenv('FASTRTPS_DEFAULT_PROFILES_FILE', str(broken))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')   # up sets it too
    assert main(['up', '--only', 'sim']) == Exit.USAGE
    out, err = capsys.readouterr()
    assert f'the Fast DDS profiles file {broken}' in err and 'nothing was started' in err
    assert 'starting' not in out


@pytest.mark.node
def test_a_refusal_before_connecting_ends_the_json_output_too(domain_id, capsys):
    assert main(['--json', 'collect', '5', '--region', 'Z']) == Exit.USAGE
    captured = capsys.readouterr()
    result = json.loads(captured.out.splitlines()[-1])
    assert result['exit_code'] == 2 and not result['ok']
    assert 'unknown region "Z"' in result['outcome'] and 'unknown region' in captured.err


def test_a_usage_error_ends_the_json_output_too(capsys):
    """argparse's own refusals (a missing argument, a value of the wrong type) included."""
    for argv, says in ((['move', '1', '--json'], 'the following arguments are required: y'),
                       (['--json', 'move', '1', '2', 'x'], "argument phi: must be")):
        assert main(argv) == Exit.USAGE
        captured = capsys.readouterr()
        result = json.loads(captured.out.splitlines()[-1])
        assert result == {'ok': False, 'error_string': result['outcome'],
                          'outcome': result['outcome'], 'exit_code': 2}
        assert says in result['outcome'] and says in captured.err and 'usage:' in captured.err
    assert main(['move', '1']) == Exit.USAGE and not capsys.readouterr().out


def test_version_says_which_flexarm_this_is(capsys):
    with pytest.raises(SystemExit):
        arguments.build_parser().parse_args(['--version'])
    assert capsys.readouterr().out.strip() == f'flexarm {metadata.version("flexarm-bringup")}'
    assert main(['--version']) == 0


def test_help_shows_defaults_and_what_each_option_governs(capsys):
    assert main(['move', '--help']) == 0
    out = ' '.join(capsys.readouterr().out.split())     # unwrapped
    for default in ('predictive', '300.0', '30.0', '0.0', '0'):
        assert f'(default: {default})' in out
    assert ('CLOSED_LOOP and AUTO correct until within it (0: the compensator\'s default); '
            'RIGID/PREDICTIVE: if given, refused before moving when the plan\'s 95 % error '
            'bound exceeds it, else the measured error must be within it (TOLERANCE_NOT_MET)'
            ) in out
    assert '--max-corrections N CLOSED_LOOP only: corrective moves after the first' in out
    assert main(['--help']) == 0
    out = capsys.readouterr().out
    assert 'exit codes:' in out and '130  interrupted' in out and '--quiet' in out


@pytest.mark.parametrize('name', ['bag', 'study', 'keygen'])
def test_offline_commands_take_only_their_own_options(name, capsys):
    assert main([name, '--help']) == 0
    out = capsys.readouterr().out
    assert '--domain-id' not in out and '--wait' not in out and '--quiet' in out


ACTION_HELP = [(['bag', 'info'], ['PATH'], ['--out', '--namespace']),
               (['bag', 'export'], ['--out DIR', '--namespace'], []),
               (['model', 'list'], ['--models', '--namespace'], ['--wait', '--domain-id',
                                                                  'VERSION']),
               (['model', 'use'], ['VERSION', '--wait', '--domain-id'], ['--models']),
               (['param', 'get'], ['NODE NAME'], ['VALUE', 'PREFIX']),
               (['param', 'list'], ['NODE [PREFIX]'], ['VALUE'])]


@pytest.mark.parametrize('argv, shown, absent', ACTION_HELP,
                         ids=[' '.join(argv) for argv, _, _ in ACTION_HELP])
def test_each_action_shows_only_its_own_arguments(argv, shown, absent, capsys):
    """`bag info --help` is info's: export's --out is not there (nor taken)."""
    assert main([*argv, '--help']) == 0
    out = ' '.join(capsys.readouterr().out.split())     # unwrapped
    assert all(word in out for word in [*shown, '--quiet']), out
    assert not any(word in out for word in absent), out


@pytest.mark.node
def test_no_graph_names_the_domain_the_cause_and_shows_the_wait(domain_id, capsys):
    started = time.monotonic()
    assert main(['move', *A1, '--wait', '2', '--domain-id', str(domain_id)]) == Exit.NO_GRAPH
    assert time.monotonic() - started < 15
    err = capsys.readouterr().err
    assert (f'flexarm move: no flexarm graph in ROS_DOMAIN_ID={domain_id} after 2 s '
            '(/move_to_pose not found): start one with `flexarm up`') in err
    assert '--domain-id' in err and 'Traceback' not in err
    assert f'waiting for the flexarm graph in ROS_DOMAIN_ID={domain_id} ...' in err


@pytest.mark.node
@pytest.mark.parametrize('flag', ['--quiet', '--json'])
def test_quiet_and_json_show_no_progress(flag, domain_id, capsys):
    assert main([flag, 'collect', '5', '--wait', '1.5']) == Exit.NO_GRAPH   # env's domain
    captured = capsys.readouterr()
    assert 'waiting for' not in captured.err
    assert f'ROS_DOMAIN_ID={domain_id} after 1.5 s' in captured.err
    if flag == '--json':
        assert json.loads(captured.out.splitlines()[-1])['exit_code'] == 3


def test_an_interrupt_never_lands_inside_a_ros_message_conversion():
    """rclpy's C++ layer turns an exception raised in a generated message module into a
    RuntimeError (the goal would not be cancelled): there the signal is sent again later."""
    from flexarm_cli.graph import interrupt_handler

    delivered = []
    previous = signal.signal(signal.SIGUSR1, lambda signum, frame: delivered.append(signum))
    try:
        inside = {'interrupt': interrupt_handler, 'signal': signal, 'sys': sys}
        exec(compile('interrupt(signal.SIGUSR1, sys._getframe())',
                     '/venv/site-packages/sensor_msgs/msg/_joint_state.py', 'exec'), inside)
        deadline = time.monotonic() + 5.0
        while not delivered and time.monotonic() < deadline:
            time.sleep(0.01)
        assert delivered == [signal.SIGUSR1]
        with pytest.raises(KeyboardInterrupt):
            interrupt_handler(signal.SIGUSR1, sys._getframe())
    finally:
        signal.signal(signal.SIGUSR1, previous)


@pytest.mark.node
def test_status_without_a_graph_says_so_and_exits_3(domain_id, capsys):
    import json

    assert main(['status', '--json', '--domain-id', str(domain_id)]) == Exit.NO_GRAPH
    captured = capsys.readouterr()
    assert 'nodes up: none: no flexarm graph in this domain' in captured.out
    assert 'model driving the arm (compensator): none' in captured.out
    status = json.loads(captured.out.splitlines()[-1])
    assert status['domain_id'] == domain_id and not any(status['nodes'].values())
    assert f'no flexarm graph in ROS_DOMAIN_ID={domain_id}' in captured.err


def test_model_list_marks_the_current_model_and_says_why_one_is_unusable(tmp_path, capsys):
    from flexarm_deflection.model_store import write_current

    (tmp_path / 'b-rbf-v1.model').write_bytes(b'not a model')
    write_current(tmp_path, 1, 'rbf', str(tmp_path / 'b-rbf-v1.model'), '')
    assert main(['model', 'list', '--models', str(tmp_path)]) == Exit.OK
    out = capsys.readouterr().out
    assert '* v1: unusable:' in out and 'not a model file' in out


@pytest.mark.parametrize('command', ['up', 'demo', 'benchmark'])
def test_ideal_switches_every_error_source_off_for_the_simulator(command):
    from flexarm_cli import build_parser
    from flexarm_cli.common import world_settings

    parser = build_parser()
    assert world_settings(parser.parse_args([command])) == {}         # config/sim.yaml's world
    assert world_settings(parser.parse_args([command, '--ideal'])) == {
        'error_sources': {'enabled': False}}
