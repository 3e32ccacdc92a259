"""The command line's parser: every subcommand, its arguments and options, checked before
anything connects."""
from __future__ import annotations

import argparse
import json
import math
import textwrap
from collections.abc import Callable
from importlib import metadata
from typing import Any

from flexarm_bringup.domains import MAX_DOMAIN_ID
from flexarm_cli.accuracy import cmd_accuracy
from flexarm_cli.common import IDEAL_HELP, learner_default, node_default
from flexarm_cli.experiments import cmd_benchmark, cmd_demo, cmd_study
from flexarm_cli.graph import cmd_down, cmd_ps, cmd_rehearse, cmd_status, cmd_up
from flexarm_cli.integration import cmd_param, cmd_urdf
from flexarm_cli.learning import (
    cmd_collect,
    cmd_model,
    cmd_payload,
    cmd_refresh,
    cmd_train,
)
from flexarm_cli.motion import cmd_cancel, cmd_move
from flexarm_cli.site import cmd_bag, cmd_calibrate, cmd_keygen, cmd_site
from flexarm_control.execution.modes import MODE_LABELS
from flexarm_core import topics
from flexarm_core.paths import RESULTS_DIR
from flexarm_learning.choices import DEFAULT_KIND, KINDS, LEARNING_CURVE, SPLITS
from flexarm_recording.results.outcome_text import (
    EXIT_MEANINGS,
)

UINT32_MAX = 2 ** 32 - 1


class UsageError(Exception):
    """A usage error, said as argparse says it (``prog: error: …``), for the caller to print
    and, under ``--json``, to end stdout with."""


class _Parser(argparse.ArgumentParser):
    """argparse's parser, but a usage error is raised, not printed and exited on: ``--json``
    must end stdout with a JSON line then too."""

    def error(self, message: str) -> None:      # type: ignore[override]
        raise UsageError(f'{self.format_usage()}{self.prog}: error: {message}')


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter,
                     argparse.RawDescriptionHelpFormatter):
    """Shows each option's default, unless it is empty or its help says what it is."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        default = action.default
        if (default is None or default is False or default == '' or default == {}
                or '(default' in (action.help or '')):
            return action.help
        return super()._get_help_string(action)


def _checked(convert: Callable[[str], Any], ok: Callable[[Any], bool],
             rule: str) -> Callable[[str], Any]:
    """An argparse type: ``convert(text)`` if that works and the value is ``ok``."""
    def parse(text: str) -> Any:
        try:
            value = convert(text)
        except ValueError:
            value = None
        if value is None or not ok(value):
            raise argparse.ArgumentTypeError(f'must be {rule}, got {text!r}')
        return value
    return parse


def _json_object(text: str) -> dict[str, Any]:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f'not valid JSON ({exc}): {text!r}') from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f'must be a JSON object, e.g. \'{{"hidden": [10]}}\', '
                                         f'got {text!r}')
    return value


_positive_int = _checked(int, lambda v: 0 < v <= UINT32_MAX, 'a whole number > 0')
_natural = _checked(int, lambda v: 0 <= v <= UINT32_MAX, 'a whole number >= 0')
_domain = _checked(int, lambda v: 0 <= v <= MAX_DOMAIN_ID, f'a ROS domain 0..{MAX_DOMAIN_ID}')
_port = _checked(int, lambda v: 0 < v < 2 ** 16, 'a TCP port 1..65535')
_finite = _checked(float, math.isfinite, 'a finite number')
_non_negative = _checked(float, lambda v: math.isfinite(v) and v >= 0, 'a number >= 0')
_positive = _checked(float, lambda v: math.isfinite(v) and v > 0, 'a number > 0')


def _output_options(parser: argparse.ArgumentParser, default: Any) -> None:
    """--json and --quiet, accepted before and after the subcommand."""
    parser.add_argument('--json', action='store_true', default=default,
                        help='end the output with one line of JSON holding the result '
                             '(SI units; implies --quiet)')
    parser.add_argument('--quiet', action='store_true', default=default,
                        help='no progress output (bars, waiting lines, goal feedback)')
    parser.add_argument('--site', default=None if default is False else default, metavar='DIR',
                        help="the site folder: its config/ over the clone's, its calibration, "
                             'data, models and runs (default: $FLEXARM_SITE; one is written by '
                             '`flexarm site init DIR`)')


def _graph_options(parser: argparse.ArgumentParser, graph: str) -> None:
    """--domain-id: of the graph a command starts ('start': a free one by default; 'up': the
    exported one, else a free one) or of the running graph it talks to ('running', 'wait': the
    environment's, as rclpy takes it); and --wait for the servers of the commands that send
    them requests ('wait')."""
    parser.add_argument('--domain-id', type=_domain, default=None, metavar='N', help={
        'start': 'ROS_DOMAIN_ID to start the graph in (default: a free one)',
        'up': 'ROS_DOMAIN_ID to start the graph in (default: the exported ROS_DOMAIN_ID, '
              'refused if another graph or process holds it; a free one if none is exported)',
    }.get(graph, 'ROS_DOMAIN_ID of the running graph (default: the environment\'s, else 0)'))
    if graph == 'wait':
        parser.add_argument('--wait', type=_positive, default=30.0, metavar='S',
                            help='[s] to wait for the graph\'s servers to answer')
        _namespace_option(parser)


def _namespace_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--namespace', type=_namespace, default='', metavar='NS',
                        help='the arm\'s namespace (flexarm up --namespace NS; default none)')


def _namespace(value: str) -> str:
    name = value.strip('/')
    if name and not all(part.isidentifier() for part in name.split('/')):
        raise argparse.ArgumentTypeError(f'{value!r} is not a ROS namespace (letters, digits, '
                                         '_ and / between names)')
    return name


def _calibrate_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('--reference-topic', default=topics.TIP_POSE_TRUTH, metavar='TOPIC',
                   help='flexarm_msgs/TipPose of the reference instrument (a laser tracker at '
                        "the tool point); in simulation the simulator's ground truth")
    p.add_argument('--timeout', type=_positive, default=120.0, metavar='S',
                   help='[s] per pose, for the move and for the reference')
    p.add_argument('--file', default='', metavar='PATH',
                   help="where to store it (default: calibration/tool_camera.json, the vision "
                        "node's tool_calibration_file)")
    p.add_argument('--camera', action='store_true',
                   help="first calibrate the camera's own parameters from the plate (focal "
                        'length over stand-off, radial distortion k1, k2) at the same poses: '
                        'for a camera refocused, remounted or off its camera_info')
    p.add_argument('--camera-file', default='', metavar='PATH',
                   help="where to store the camera's (default: calibration/camera.json, the "
                        "vision node's camera_calibration_file)")


def _move_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('x', type=_finite, help='target x [mm] (horizontal, base frame)')
    p.add_argument('y', type=_finite, help='target y [mm] (up)')
    p.add_argument('phi', type=_finite, help='target tool angle [deg] from +x')
    p.add_argument('--mode', choices=MODE_LABELS,
                   default='predictive',
                   help='rigid: rigid inverse kinematics; predictive: compensate the learned '
                        'deflection (needs a model); closed_loop: predictive (rigid without a '
                        'model), then corrected from the measured tip; auto: predictive where '
                        'the plan\'s 95 %% error bound is within the tolerance, else '
                        'closed_loop')
    p.add_argument('--position-tolerance', type=_non_negative, default=0.0, metavar='MM',
                   help='[mm] CLOSED_LOOP and AUTO correct until within it (0: the '
                        'compensator\'s default); RIGID/PREDICTIVE: if given, refused before '
                        'moving when the plan\'s 95 %% error bound exceeds it, else the '
                        'measured error must be within it (TOLERANCE_NOT_MET)')
    p.add_argument('--angle-tolerance', type=_non_negative, default=0.0, metavar='DEG',
                   help='[deg] as --position-tolerance, for the tool angle')
    p.add_argument('--max-corrections', type=_natural, default=0, metavar='N',
                   help='CLOSED_LOOP only: corrective moves after the first (0: the '
                        'compensator\'s default)')
    p.add_argument('--allow-extrapolation', action='store_true',
                   help='run a PREDICTIVE goal beyond the learned data, or whose error bound '
                        'exceeds its tolerance (with a warning), instead of refusing it')
    p.add_argument('--trial', default='', help='trial name for logs and bags')
    p.add_argument('--dry-run', action='store_true',
                   help='only plan: print the commanded pose, joints, predicted deflection, '
                        'distance to the learned data and model; nothing moves')
    p.add_argument('--timeout', type=_positive, default=300.0, metavar='S',
                   help='[s] for the goal; then it is cancelled')


def _collect_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('count', type=_positive_int, metavar='N', help='samples to collect')
    p.add_argument('--region', default='',
                   help='region preset of config/learner.yaml (default: the learner\'s, '
                        f'{learner_default("default_region")})')
    p.add_argument('--strategy', default='',
                   help='sobol | halton | lhs | random | active (each pose where the model '
                        'so far is least sure; default: the learner\'s, '
                        f'{learner_default("default_strategy")})')
    p.add_argument('--seed', type=_natural, default=0, help='seed of the sampling strategy')
    p.add_argument('--dataset', default='',
                   help='dataset name: data/NAME.jsonl (default: the learner\'s, '
                        f'{learner_default("default_dataset")})')
    p.add_argument('--payload', type=_non_negative, metavar='KG',
                   help='[kg] declare the payload the arm carries first (stored with every '
                        'sample; default: as declared before)')
    p.add_argument('--timeout', type=_positive, default=3600.0, metavar='S',
                   help='[s] for the collection; then it is cancelled')


def _refresh_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('--count', type=_natural, default=0, metavar='N',
                   help='samples to take (default: the learner\'s refresh_samples, '
                        f'{learner_default("refresh_samples")})')
    p.add_argument('--region', default='',
                   help='region preset to refresh (default: the ones the model health '
                        'reports stale)')
    p.add_argument('--force', action='store_true',
                   help='refresh --region even where the model health sees the model fit '
                        '(it would fit measurement noise)')
    p.add_argument('--timeout', type=_positive, default=1800.0, metavar='S',
                   help='[s] for the refresh; then it is cancelled')


def _payload_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('kg', nargs='?', type=_non_negative, metavar='KG',
                   help='[kg] the payload the arm carries from now on (default: only show it)')


KIND_HELP = ('predictor kind: auto (the best of kinematic, greybox and gp by cross-validation) '
             '| kinematic | greybox | gp | mlp | rbf')


def _kind_help() -> str:
    """KIND_HELP and the learner's default kind, read so that the help cannot drift."""
    return f"{KIND_HELP} (default: the learner's, {learner_default('default_kind')})"


def _train_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('kind', nargs='?', default='', help=_kind_help())
    p.add_argument('--settings', type=_json_object, default={},
                   help='kind-specific settings, a JSON object, e.g. \'{"hidden": [10]}\' '
                        '(default: the kind\'s)')
    p.add_argument('--dataset', default='', help='dataset name (default: the learner\'s)')
    p.add_argument('--timeout', type=_positive, default=300.0, metavar='S',
                   help='[s] for the training')


def _up_arguments(p: argparse.ArgumentParser) -> None:
    _namespace_option(p)
    p.add_argument('--ideal', action='store_true', help=IDEAL_HELP)
    p.add_argument('--robot', default='sim', help='controller entry of config/graph.yaml')
    p.add_argument('--record', default='', metavar='NAME', help='record bags/NAME/NAME.mcap')
    p.add_argument('--record-images', action='store_true',
                   help='with --record: also record /camera/image_raw (~9 MB/s)')
    p.add_argument('--foxglove', nargs='?', type=_port, const=0, default=None, metavar='PORT',
                   help='serve the live graph to Foxglove at ws://HOST:PORT (config/'
                        f'foxglove.yaml: HOST {node_default("foxglove", "host")}, default '
                        f'PORT {node_default("foxglove", "port")})')
    p.add_argument('--rtf', type=_positive, default=None,
                   help="simulator real-time factor (default: the simulator's "
                        f'real_time_factor, {node_default("simulator", "real_time_factor")})')
    p.add_argument('--name', default='', help='run folder runs/NAME (default: up-DATE-TIME)')
    p.add_argument('--timeout', type=_positive, default=60.0, metavar='S',
                   help='[s] to become ready')
    p.add_argument('--link-key', default='', metavar='FILE',
                   help='site key of the controller link (made by flexarm keygen FILE); '
                        'required when the controller is not on this machine')
    p.add_argument('--discovery', choices=['localhost', 'subnet'], default='localhost',
                   help='DDS range (default: this machine only); subnet: anyone on the '
                        'network can command the arm (no DDS-Security in these wheels)')
    p.add_argument('--only', type=lambda text: tuple(text.split(',')), default=(),
                   metavar='NODES', help='start only these nodes of config/graph.yaml, comma-'
                   'separated, flexarm_ prefix optional (e.g. sim,vision); the rest of the '
                   'graph runs on other hosts of the domain (default: the whole graph)')
    p.add_argument('--outlive-parent', action='store_true',
                   help='keep the graph running after the process that started `up` has '
                        'ended, e.g. `nohup flexarm up --outlive-parent &` (default: it stops '
                        'with that process as on Ctrl-C, so a script, test or shell that dies '
                        'leaves no graph behind; a terminal closing stops it unless nohup)')


def _experiment_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('--samples', type=_positive_int, default=40,
                   help='learning samples per region')
    p.add_argument('--kind', default='', help=_kind_help())
    p.add_argument('--rtf', type=_positive, default=10.0, help='simulator real-time factor')
    p.add_argument('--seed', type=_natural, default=1, help='seed of samples and targets')
    p.add_argument('--name', default='',
                   help='results/NAME, bags/NAME, runs/NAME (default: COMMAND-DATE-TIME)')
    p.add_argument('--no-record', action='store_true', help='do not write a bag')
    p.add_argument('--ideal', action='store_true', help=IDEAL_HELP)


def _benchmark_arguments(p: argparse.ArgumentParser) -> None:
    _experiment_arguments(p)
    p.add_argument('--random', type=_natural, default=50,
                   help='held-out random targets per region A and B')


def _study_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('--region', default='paper', help='region preset of config/learner.yaml')
    p.add_argument('--seeds', type=_positive_int, default=3,
                   help='repetitions of every configuration')
    p.add_argument('--quick', action='store_true', help='small grid, for a smoke run')
    p.add_argument('--out', default=str(RESULTS_DIR / 'study'),
                   help='results go to OUT/REGION/')


def _kinds(text: str) -> tuple[str, ...]:
    kinds = tuple(k.strip() for k in text.split(',') if k.strip())
    unknown = [k for k in kinds if k not in KINDS]
    if not kinds or unknown:
        raise argparse.ArgumentTypeError(f'must be kinds among {", ".join(KINDS)}, '
                                         f'comma-separated, got {text!r}')
    return kinds


def _sizes(text: str) -> tuple[int, ...]:
    return tuple(_positive_int(t) for t in text.split(',') if t.strip())


def _accuracy_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('--urdf', required=True, help="the arm's URDF")
    p.add_argument('--tip', required=True, help='the link the measured target is fixed to')
    p.add_argument('--measurements', required=True, metavar='FILE.csv',
                   help='one row per measured pose: a column per URDF joint, x, y, z [m] of '
                        'the target in the instrument frame; optional qx qy qz qw, payload, '
                        'temperature, group (docs/accuracy.md)')
    p.add_argument('--train', type=_positive_int, default=40, metavar='N',
                   help='rows to learn from; the others judge the model')
    p.add_argument('--splits', type=_positive_int, default=SPLITS,
                   help='random splits, figures averaged over them')
    p.add_argument('--seed', type=_natural, default=0, help='seed of the first split')
    p.add_argument('--kinds', type=_kinds, default=DEFAULT_KIND,
                   help=f'comma-separated: {", ".join(KINDS)} (the first gets the learning '
                        'curve)')
    p.add_argument('--curve', type=_sizes, default=','.join(map(str, LEARNING_CURVE)),
                   metavar='N,N,...',
                   help="training sizes of the learning curve ('' for none)")
    p.add_argument('--plot', default=None, metavar='DIR', help='write the figures to DIR')


def _bag_path(p: argparse.ArgumentParser) -> None:
    p.add_argument('path', metavar='PATH', help='bag folder (bags/NAME) or .mcap file')


def _bag_export_arguments(p: argparse.ArgumentParser) -> None:
    _bag_path(p)
    p.add_argument('--out', default='', metavar='DIR',
                   help='export folder (default: the bag folder)')
    _namespace_option(p)


def _site_init_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('dir', metavar='DIR', help='the site folder (made if missing; existing '
                   'files are never overwritten)')
    p.add_argument('--robot', choices=['bridge', 'ros2_control'], default='bridge',
                   help='the controller side of the site')


def _model_list_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('--models', default='', metavar='DIR',
                   help="the learner's model directory (default: models/, models/NS with "
                        '--namespace NS)')
    _namespace_option(p)


def _model_use_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('version', metavar='VERSION',
                   help='the model version (see `flexarm model list`)')


def _urdf_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('file', nargs='?', default='', metavar='FILE',
                   help='where to write it (default: stdout)')
    p.add_argument('--robot', default='sim', help='controller entry of config/graph.yaml')


def _param_arguments(p: argparse.ArgumentParser, action: str) -> None:
    """NODE and what ``action`` takes after it: get NAME, set NAME VALUE, list [PREFIX],
    describe NAME (``value`` is None but for set: cmd_param reads it)."""
    p.add_argument('node', metavar='NODE',
                   help='the node\'s name (e.g. flexarm_learner; under --namespace)')
    if action == 'list':
        p.add_argument('name', nargs='?', default='', metavar='PREFIX',
                       help='only the parameters whose names start with it (default: all)')
    else:
        p.add_argument('name', metavar='NAME', help='the parameter')
    if action == 'set':
        p.add_argument('value', metavar='VALUE',
                       help='read as YAML as ros2 param set reads it (2.5, true, text, '
                            '"[0.0, 1.0]"); a whole number sets a double parameter')
    else:
        p.set_defaults(value=None)


def _keygen_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('path', help='key file to create')


def _rehearse_arguments(p: argparse.ArgumentParser) -> None:
    _namespace_option(p)
    p.add_argument('--domain-id', type=_domain, default=None, metavar='N',
                   help='ROS_DOMAIN_ID of the running graph that drives it, or of the '
                        'one `flexarm up` will start (default: the exported one)')


def _down_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('--domain-id', type=_domain, default=None, metavar='N',
                   help='ROS_DOMAIN_ID of the running graph to stop (default: the only graph '
                        'running on this machine; see flexarm ps)')
    p.add_argument('--namespace', type=_namespace, default=None, metavar='NS',
                   help="the arm's namespace (flexarm up --namespace NS; default: whichever "
                        'arm runs in the domain, if only one does)')
    p.add_argument('--timeout', type=_positive, default=30.0, metavar='S',
                   help='[s] to wait for the graph to end (its supervisor stops each node '
                        'with SIGINT, then SIGTERM, then SIGKILL)')


DESCRIPTION = 'flexarm: the command line of the flexarm system.'
Command = Callable[[argparse.Namespace], dict[str, Any]]
Arguments = Callable[[argparse.ArgumentParser], None]
# an action of a subcommand (bag info, bag export): (its help, its arguments, its graph
# options); a parser of its own, so that each action shows and takes only what it uses
ActionEntry = tuple[str, Arguments, str | None]
BAG_ACTIONS: dict[str, ActionEntry] = {
    'info': ('its topics, message counts and duration', _bag_path, None),
    'export': ('its trials as CSV + PNG and its figures, into --out', _bag_export_arguments,
               None),
}
MODEL_ACTIONS: dict[str, ActionEntry] = {
    'list': ('every trained model (a refresh: of which version, its samples, residual '
             'before/after); * = current', _model_list_arguments, None),
    'use': ('make an earlier model current again (roll back); the compensator switches to it',
            _model_use_arguments, 'wait'),
}
PARAM_ACTIONS: dict[str, ActionEntry] = {
    'get': ("a parameter's value", lambda p: _param_arguments(p, 'get'), 'wait'),
    'set': ('set a parameter (a node that refuses says why)',
            lambda p: _param_arguments(p, 'set'), 'wait'),
    'list': ("the node's parameters and their values", lambda p: _param_arguments(p, 'list'),
             'wait'),
    'describe': ("a parameter's type, description (unit first), range, whether it is "
                 'read-only, and its value', lambda p: _param_arguments(p, 'describe'), 'wait'),
}
SITE_ACTIONS: dict[str, ActionEntry] = {
    'init': ("write the site folder's starting point", _site_init_arguments, None),
}
# subcommand: (what runs it, its arguments or its actions (args.action), graph options
# (_graph_options): None = none, 'start' = it starts a graph, 'up' = it starts one in the
# exported domain, 'running' = it asks a running one, 'wait' = it sends requests to a running
# one). The command's docstring is its help.
SUBCOMMANDS: dict[str, tuple[Command, Arguments | dict[str, ActionEntry], str | None]] = {
    'up': (cmd_up, _up_arguments, 'up'),
    'status': (cmd_status, _namespace_option, 'running'),
    'ps': (cmd_ps, lambda p: None, None),
    'rehearse': (cmd_rehearse, _rehearse_arguments, None),
    'down': (cmd_down, _down_arguments, None),
    'move': (cmd_move, _move_arguments, 'wait'),
    'collect': (cmd_collect, _collect_arguments, 'wait'),
    'train': (cmd_train, _train_arguments, 'wait'),
    'refresh': (cmd_refresh, _refresh_arguments, 'wait'),
    'payload': (cmd_payload, _payload_arguments, 'wait'),
    'cancel': (cmd_cancel, lambda p: None, 'wait'),
    'demo': (cmd_demo, _experiment_arguments, 'start'),
    'benchmark': (cmd_benchmark, _benchmark_arguments, 'start'),
    'study': (cmd_study, _study_arguments, None),
    'accuracy': (cmd_accuracy, _accuracy_arguments, None),
    'bag': (cmd_bag, BAG_ACTIONS, None),
    'model': (cmd_model, MODEL_ACTIONS, None),
    'keygen': (cmd_keygen, _keygen_arguments, None),
    'site': (cmd_site, SITE_ACTIONS, None),
    'calibrate': (cmd_calibrate, _calibrate_arguments, 'wait'),
    'urdf': (cmd_urdf, _urdf_arguments, None),
    'param': (cmd_param, PARAM_ACTIONS, None),
}


def build_parser() -> argparse.ArgumentParser:
    epilog = 'exit codes:\n' + '\n'.join(
        textwrap.fill(text, 79, initial_indent=f'  {int(code):>3}  ', subsequent_indent=' ' * 7)
        for code, text in EXIT_MEANINGS.items())
    parser = _Parser(prog='flexarm', description=DESCRIPTION, epilog=epilog,
                     formatter_class=_HelpFormatter)
    parser.add_argument('--version', action='version',
                        version=f'flexarm {metadata.version("flexarm-bringup")}')
    _output_options(parser, False)
    output = _Parser(add_help=False)
    _output_options(output, argparse.SUPPRESS)     # after the subcommand: only when given
    sub = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')
    for name, (run, arguments, graph) in SUBCOMMANDS.items():
        _add_parser(sub, name, run.__doc__ or '', arguments, graph, output)
    return parser


def _add_parser(sub: argparse._SubParsersAction, name: str, text: str,
                arguments: Arguments | dict[str, ActionEntry], graph: str | None,
                output: argparse.ArgumentParser) -> None:
    """The parser of a subcommand or of one of its actions (``output``: --json, --quiet and
    --site after it too)."""
    p = sub.add_parser(name, help=text, description=text, parents=[output],
                       formatter_class=_HelpFormatter)
    if isinstance(arguments, dict):
        actions = p.add_subparsers(dest='action', required=True, metavar='ACTION')
        for action, (help_text, action_arguments, action_graph) in arguments.items():
            _add_parser(actions, action, help_text, action_arguments, action_graph, output)
    else:
        arguments(p)
    if graph is not None:
        _graph_options(p, graph)
