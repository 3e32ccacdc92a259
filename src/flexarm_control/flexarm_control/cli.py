"""``flexarm``: the command line of the flexarm system.

Humans type millimetres and degrees; everything below the CLI is SI. Every subcommand prints
for humans and, with ``--json``, ends its output with one line of JSON holding its result.
The graph must be running (``flexarm up``) for move/collect/train, in the same ROS_DOMAIN_ID.
DDS discovery stays on this machine (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) unless the
environment sets another range or ``flexarm up --discovery subnet`` widens it on purpose.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
from collections.abc import Callable, Sequence
from typing import Any

COMMANDS: dict[str, Callable[[argparse.Namespace], dict[str, Any]]] = {}


def command(func: Callable[[argparse.Namespace], dict[str, Any]]):
    COMMANDS[func.__name__.removeprefix('cmd_')] = func
    return func


def mm(value_m: float) -> float:
    return value_m * 1e3


def deg(value_rad: float) -> float:
    return math.degrees(value_rad)


def pose_dict(pose: Any) -> dict[str, float]:
    """A PlanarPose as a JSON-able dict in SI units."""
    return {'x': pose.x, 'y': pose.y, 'phi': pose.phi}


def _connect(args: argparse.Namespace, learner: bool):
    from flexarm_control.client import init_client

    client = init_client(args.domain_id)
    client.wait_until_ready(timeout=args.wait, learner=learner)
    return client


def _shutdown(client: Any) -> None:
    import rclpy

    client.destroy_node()
    rclpy.try_shutdown()


@command
def cmd_move(args: argparse.Namespace) -> dict[str, Any]:
    """Move the tip to X Y PHI [mm mm deg]."""
    from flexarm_control.client import GoalRejected

    client = _connect(args, learner=False)

    def show(fb: Any) -> None:
        measured = (f' measured ({fb.measured_pose.x * 1e3:.2f}, {fb.measured_pose.y * 1e3:.2f}, '
                    f'{deg(fb.measured_pose.phi):.3f}) error {mm(fb.position_error):.3f} mm '
                    f'{deg(fb.angle_error):.4f} deg' if fb.measured else '')
        print(f'  [{fb.iteration}] {fb.phase}{measured}', flush=True)

    try:
        result = client.move_to(args.x / 1e3, args.y / 1e3, math.radians(args.phi),
                                mode=args.mode,
                                position_tolerance=args.position_tolerance / 1e3,
                                angle_tolerance=math.radians(args.angle_tolerance),
                                max_iterations=args.max_iterations, trial=args.trial,
                                timeout=args.timeout,
                                allow_extrapolation=args.allow_extrapolation, feedback=show)
    except GoalRejected as exc:
        return {'ok': False, 'error_code': None, 'error_string': str(exc)}
    finally:
        _shutdown(client)
    out = {'ok': result.error_code == 0, 'error_code': result.error_code,
           'error_string': result.error_string, 'mode': args.mode,
           'target': {'x': args.x / 1e3, 'y': args.y / 1e3, 'phi': math.radians(args.phi)},
           'joint_positions': list(result.joint_positions),
           'commanded_pose': pose_dict(result.commanded_pose),
           'predicted_deflection': pose_dict(result.predicted_deflection),
           'measured': result.measured, 'measured_pose': pose_dict(result.measured_pose),
           'position_error': result.position_error, 'angle_error': result.angle_error,
           'iterations': result.iterations,
           'compensation_iterations': result.compensation_iterations,
           'data_distance': result.data_distance, 'prediction_std': result.prediction_std}
    learned = (f'; {result.data_distance:.2f} sample spacings from the learned data, model '
               f'std {mm(result.prediction_std):.3f} mm'
               if result.data_distance or result.prediction_std else '')
    if out['ok']:
        print(f'reached in {result.iterations} move(s)' + (
            f': error {mm(result.position_error):.3f} mm, {deg(result.angle_error):.4f} deg'
            if result.measured else ' (no measurement)') + learned
            + (f'; {result.error_string}' if result.error_string else ''))
    else:
        print(f'failed ({result.error_code}): {result.error_string}')
    return out


@command
def cmd_up(args: argparse.Namespace) -> dict[str, Any]:
    """Start the graph (one process per node), wait until ready, supervise until Ctrl-C."""
    import time

    from flexarm_control.experiment import REPO, reserved_domain
    from flexarm_control.supervisor import Graph

    name = args.name or time.strftime('up-%Y%m%d-%H%M%S')
    simulated = {'real_time_factor': args.rtf}
    link = {'link_key_file': os.path.abspath(args.link_key)} if args.link_key else {}
    params: dict[str, dict[str, Any]] = {'flexarm_sim': simulated,
                                         'flexarm_fake_controller': simulated | link,
                                         'flexarm_bridge': link}
    if args.record:
        params['flexarm_recorder'] = {'bag_name': args.record}
    discovery = args.discovery.upper()
    if discovery != 'LOCALHOST':
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = discovery
        print(f'DDS discovery widened to {discovery}: any host there that joins the ROS '
              'domain can command this arm (these DDS wheels have no security)', flush=True)
    with reserved_domain(args.domain_id) as domain:
        graph = Graph(domain, REPO / 'runs' / name, robot=args.robot, parameters=params,
                      optional=('flexarm_recorder',) if args.record else (),
                      discovery=discovery)
        started, ready = time.monotonic(), None
        print(f'starting {", ".join(graph.nodes)} in ROS_DOMAIN_ID={domain}; logs in '
              f'{graph.run_dir}', flush=True)
        try:
            graph.start()
            graph.wait_ready(args.timeout)
            ready = time.monotonic() - started
            print(f'graph ready in {ready:.1f} s. In another shell: ROS_DOMAIN_ID={domain} '
                  'flexarm move 1450 -150 -45. Ctrl-C stops everything.', flush=True)
            while True:
                time.sleep(0.5)
                graph.check()
        except KeyboardInterrupt:
            pass
        finally:
            codes = graph.stop()
            print('stopped: ' + ', '.join(f'{n} ({c})' for n, c in codes.items()), flush=True)
    return {'ok': True, 'domain_id': domain, 'exit_codes': codes, 'run_dir': str(graph.run_dir)}


def _interrupt(signum: int, frame: Any) -> None:
    """SIGTERM handler: shut down like Ctrl-C."""
    raise KeyboardInterrupt


def _experiment(args: argparse.Namespace, **overrides: Any) -> dict[str, Any]:
    import time

    from flexarm_control.experiment import (ExperimentSettings, reserved_domain,
                                            run_experiment, table_text)

    settings = ExperimentSettings(
        name=args.name or time.strftime(f'{args.command}-%Y%m%d-%H%M%S'),
        samples=args.samples, kind=args.kind, real_time_factor=args.rtf,
        record=not args.no_record, seed=args.seed, **overrides)
    with reserved_domain(args.domain_id) as domain:
        summary = run_experiment(settings, domain, progress=not args.json)
    print(table_text(summary))
    print(f'results in {summary["results"]}' + (
        f', bag in {summary["bag"]}' if summary['bag'] else '') +
        f'; {summary["seconds"]:.0f} s in all')
    out = {k: v for k, v in summary.items() if k != 'trials'}
    out['ok'] = not summary['nodes_died']
    return out


@command
def cmd_demo(args: argparse.Namespace) -> dict[str, Any]:
    """Collect, train and run the paper's Table 10 targets in all three modes."""
    return _experiment(args)


@command
def cmd_benchmark(args: argparse.Namespace) -> dict[str, Any]:
    """Tables 9 and 10 plus held-out random targets, side by side with the paper."""
    return _experiment(args, random_targets=args.random, table9=True)


@command
def cmd_collect(args: argparse.Namespace) -> dict[str, Any]:
    """Collect N deflection samples with the learner."""
    from tqdm import tqdm

    client = _connect(args, learner=True)
    bar = tqdm(total=args.count, unit='sample', disable=args.json)
    try:
        result = client.collect(args.count, region=args.region, strategy=args.strategy,
                                seed=args.seed, dataset=args.dataset, timeout=args.timeout,
                                feedback=lambda fb: bar.update(fb.k - bar.n))
    finally:
        bar.close()
        _shutdown(client)
    print(f'{result.collected} collected, {result.skipped} skipped; {result.total} samples in '
          f'{result.dataset_path}' + (f' ({result.error_string})' if result.error_string else ''))
    return {'ok': result.error_code == 0, 'error_code': result.error_code,
            'error_string': result.error_string, 'collected': result.collected,
            'skipped': result.skipped, 'total': result.total,
            'dataset_path': result.dataset_path}


@command
def cmd_train(args: argparse.Namespace) -> dict[str, Any]:
    """Train a predictor (mlp, rbf, gp) on a dataset; prints the validation metrics."""
    client = _connect(args, learner=True)
    try:
        settings = json.loads(args.settings) if args.settings else {}
        response = client.train(args.kind, settings, dataset=args.dataset, timeout=args.timeout)
    finally:
        _shutdown(client)
    m = response.metrics
    if response.success:
        print(f'model v{response.model_version} at {response.model_path} '
              f'(chosen by validation: {m.selected_settings})\n'
              f'{m.validation}, {m.samples} samples: max |error| x {mm(m.max_error_x):.3f} mm, '
              f'y {mm(m.max_error_y):.3f} mm, phi {deg(m.max_error_phi):.4f} deg; mean '
              f'{mm(m.mean_error_x):.3f} mm, {mm(m.mean_error_y):.3f} mm, '
              f'{deg(m.mean_error_phi):.4f} deg')
        if len(m.excluded_samples):
            print(f'excluded as outliers: {len(m.excluded_samples)} sample(s), dataset '
                  f'indices {list(m.excluded_samples)}')
        if response.message:
            print(response.message)
    else:
        print(response.message)
    return {'ok': response.success, 'message': response.message,
            'model_version': response.model_version, 'model_path': response.model_path,
            'metrics': {k: getattr(m, k) for k in (
                'validation', 'samples', 'max_error_x', 'max_error_y', 'max_error_phi',
                'mean_error_x', 'mean_error_y', 'mean_error_phi', 'selected_settings',
                'max_slope')} | {'excluded_samples': list(m.excluded_samples)}}


@command
def cmd_bag(args: argparse.Namespace) -> dict[str, Any]:
    """Inspect a recorded bag (info) or export its trials as CSV + PNG (export)."""
    from flexarm_control.bag_tools import bag_info, export_trials, format_bag_info

    if args.action == 'info':
        info = bag_info(args.path)
        print(format_bag_info(info))
        return {'ok': True, **info}
    out_dir = args.out or str(args.path).rstrip('/')
    csv_path, png_path = export_trials(args.path, out_dir)
    print(f'trials: {csv_path}\nplot:   {png_path}')
    return {'ok': True, 'csv': str(csv_path), 'png': str(png_path)}


@command
def cmd_keygen(args: argparse.Namespace) -> dict[str, Any]:
    """Write a new site key for the controller link (give it to the PC and the controller)."""
    from flexarm_control.link_auth import make_key

    if os.path.exists(args.path):
        raise ValueError(f'{args.path} exists; a new key would lock out whoever uses it')
    path = make_key(args.path)
    print(f'site key written to {path} (mode 600). Use it on both ends: '
          f'flexarm up --robot bridge --link-key {path}, and the controller\'s configuration')
    return {'ok': True, 'path': str(path)}


@command
def cmd_study(args: argparse.Namespace) -> dict[str, Any]:
    """Tables 7 and 8 sensitivity study on the simulator (offline, no graph needed)."""
    from flexarm_control.study import main as study_main

    argv = ['--region', args.region, '--seeds', str(args.seeds)] + (
        ['--quick'] if args.quick else [])
    return {'ok': study_main(argv) == 0}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='flexarm', description=__doc__.splitlines()[0])
    # Global options, accepted before or after the subcommand.
    common = argparse.ArgumentParser(add_help=False)
    for p, default in ((parser, None), (common, argparse.SUPPRESS)):
        p.add_argument('--json', action='store_true', default=default or False,
                       help='end the output with one line of JSON holding the result')
        p.add_argument('--domain-id', type=int, default=default,
                       help='ROS_DOMAIN_ID of the graph (default: from the environment; '
                            'up/demo/benchmark: a free one)')
        p.add_argument('--wait', type=float, default=default or 30.0,
                       help='seconds to wait for the graph to be ready')
    sub = parser.add_subparsers(dest='command', required=True)
    add_parser = sub.add_parser
    sub.add_parser = lambda *a, **k: add_parser(*a, parents=[common], **k)  # type: ignore

    move = sub.add_parser('move', help=cmd_move.__doc__)
    move.add_argument('x', type=float, help='[mm]')
    move.add_argument('y', type=float, help='[mm]')
    move.add_argument('phi', type=float, help='[deg]')
    move.add_argument('--mode', choices=['rigid', 'predictive', 'closed_loop'],
                      default='predictive')
    move.add_argument('--position-tolerance', type=float, default=0.0,
                      help='[mm] closed loop stops within it (0: server default)')
    move.add_argument('--angle-tolerance', type=float, default=0.0,
                      help='[deg] (0: server default)')
    move.add_argument('--max-iterations', type=int, default=0)
    move.add_argument('--allow-extrapolation', action='store_true',
                      help='run a PREDICTIVE goal beyond the learned data (with a warning) '
                           'instead of refusing it')
    move.add_argument('--trial', default='', help='trial name for logs and bags')
    move.add_argument('--timeout', type=float, default=300.0, help='[s]')

    up = sub.add_parser('up', help=cmd_up.__doc__)
    up.add_argument('--robot', default='sim', help='controller entry of config/graph.yaml')
    up.add_argument('--record', default='', metavar='NAME', help='record bags/NAME/NAME.mcap')
    up.add_argument('--rtf', type=float, default=1.0, help='simulator real-time factor')
    up.add_argument('--name', default='', help='run folder name under runs/')
    up.add_argument('--timeout', type=float, default=60.0, help='[s] to become ready')
    up.add_argument('--link-key', default='', metavar='FILE',
                    help='site key of the controller link (flexarm keygen); required when the '
                         'controller is not on this machine')
    up.add_argument('--discovery', choices=['localhost', 'subnet'], default='localhost',
                    help='DDS discovery range; subnet exposes the graph to the network')

    for name, func in (('demo', cmd_demo), ('benchmark', cmd_benchmark)):
        p = sub.add_parser(name, help=func.__doc__)
        p.add_argument('--samples', type=int, default=40, help='learning samples per region')
        p.add_argument('--kind', default='', help="predictor kind (default: the learner's)")
        p.add_argument('--rtf', type=float, default=10.0, help='simulator real-time factor')
        p.add_argument('--seed', type=int, default=1)
        p.add_argument('--name', default='', help='results/NAME, bags/NAME, runs/NAME')
        p.add_argument('--no-record', action='store_true', help='do not write a bag')
        if name == 'benchmark':
            p.add_argument('--random', type=int, default=50,
                           help='held-out random targets per region A and B')

    collect = sub.add_parser('collect', help=cmd_collect.__doc__)
    collect.add_argument('count', type=int)
    collect.add_argument('--region', default='', help='region preset (config/learner.yaml)')
    collect.add_argument('--strategy', default='', help='sobol | halton | lhs | random')
    collect.add_argument('--seed', type=int, default=0)
    collect.add_argument('--dataset', default='', help='dataset name')
    collect.add_argument('--timeout', type=float, default=3600.0, help='[s]')

    train = sub.add_parser('train', help=cmd_train.__doc__)
    train.add_argument('kind', nargs='?', default='',
                       help="mlp | rbf | gp (default: the learner's, gp)")
    train.add_argument('--settings', default='', help='JSON object, e.g. \'{"hidden": [10]}\'')
    train.add_argument('--dataset', default='', help='dataset name')
    train.add_argument('--timeout', type=float, default=300.0, help='[s]')

    study = sub.add_parser('study', help=cmd_study.__doc__)
    study.add_argument('--region', default='paper', help='region preset')
    study.add_argument('--seeds', type=int, default=3)
    study.add_argument('--quick', action='store_true', help='small grid, for a smoke run')

    bag = sub.add_parser('bag', help=cmd_bag.__doc__)
    bag.add_argument('action', choices=['info', 'export'])
    bag.add_argument('path', help='bag folder (bags/NAME) or .mcap file')
    bag.add_argument('--out', default='', help='export folder (default: the bag folder)')

    keygen = sub.add_parser('keygen', help=cmd_keygen.__doc__)
    keygen.add_argument('path', help='key file to create')
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    # SIGTERM stops a command like Ctrl-C does, so that a graph it started is shut down
    # (its nodes run in sessions of their own and do not get the signal themselves).
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        result = COMMANDS[args.command](args)
    except (TimeoutError, ValueError, RuntimeError) as exc:
        result = {'ok': False, 'error_string': str(exc)}
        print(f'flexarm {args.command}: {exc}', file=sys.stderr)
    except KeyboardInterrupt:
        result = {'ok': False, 'error_string': 'interrupted'}
    if args.json:
        print(json.dumps(result))
    return 0 if result.get('ok', True) else 1


if __name__ == '__main__':
    sys.exit(main())
