"""``flexarm``: the command line of the flexarm system.

Humans type millimetres and degrees; everything below the CLI is SI. Every subcommand prints
for humans and, with ``--json``, ends its output with one line of JSON holding its result.
The graph must be running (``flexarm up``) for move/collect/train, in the same ROS_DOMAIN_ID.
"""
from __future__ import annotations

import argparse
import json
import math
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
                                timeout=args.timeout, feedback=show)
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
           'compensation_iterations': result.compensation_iterations}
    if out['ok']:
        print(f'reached in {result.iterations} move(s)' + (
            f': error {mm(result.position_error):.3f} mm, {deg(result.angle_error):.4f} deg'
            if result.measured else ' (no measurement)'))
    else:
        print(f'failed ({result.error_code}): {result.error_string}')
    return out


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='flexarm', description=__doc__.splitlines()[0])
    parser.add_argument('--json', action='store_true',
                        help='end the output with one line of JSON holding the result')
    parser.add_argument('--domain-id', type=int, default=None,
                        help='ROS_DOMAIN_ID of the graph (default: from the environment)')
    parser.add_argument('--wait', type=float, default=30.0,
                        help='seconds to wait for the graph to be ready')
    sub = parser.add_subparsers(dest='command', required=True)

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
    move.add_argument('--trial', default='', help='trial name for logs and bags')
    move.add_argument('--timeout', type=float, default=300.0, help='[s]')
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
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
