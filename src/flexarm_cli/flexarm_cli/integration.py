"""``flexarm urdf`` and ``param``: what an integrator's ROS tools take from the graph, without
the ``ros2`` command line (rclpy from PyPI has none)."""
from __future__ import annotations

import argparse
import sys
from typing import Any

from flexarm_cli.common import Outcome, graph_client, timed_step, usage
from flexarm_recording.results.outcome_text import Exit


def cmd_urdf(args: argparse.Namespace) -> dict[str, Any]:
    """The robot description (URDF) the graph publishes on /robot_description, made as its
    state publisher makes it (no graph needed): to FILE (written atomically), else stdout."""
    from flexarm_bringup.launcher import load_graph, node_name, node_parameters
    from flexarm_core.atomic_file import atomic_write
    from flexarm_description.urdf_model import published_description

    try:
        name = node_name('state_publisher')
        spec = next(s for s in load_graph(args.robot) if s.name == name)
    except ValueError as exc:
        raise usage(str(exc)) from None
    text = published_description(node_parameters(spec))
    if args.file:
        atomic_write(args.file, lambda f: f.write(text.encode()))
        print(f'robot description of robot {args.robot} written to {args.file}')
    else:
        sys.stdout.write(text)
    return {'ok': True, 'robot': args.robot, 'path': args.file or None}


def cmd_param(args: argparse.Namespace) -> dict[str, Any]:
    """Get, set, list or describe the parameters of a node of the graph over its parameter
    services, as ros2 param does; a value is read as YAML (a number, true/false, text, a
    [list])."""
    import rclpy

    from flexarm_cli.parameter_text import description_text, typed_value, value_text

    _check_param(args)
    node, name = args.node, args.name
    client = graph_client(args)
    try:
        with timed_step(f'asking {node}', args):
            current = client.node_parameters(node, [name] if name and args.action != 'list'
                                             else None, args.wait)
            if args.action == 'list':
                shown = {n: v for n, v in current.items() if n.startswith(name)}
                print('\n'.join(f'{n}: {value_text(v)}' for n, v in shown.items()))
                return {'ok': True, 'node': node, 'parameters': shown}
            if current[name] is None:
                raise Outcome(f'{node} has no parameter {name} (flexarm param list {node} '
                              'shows those it has)', Exit.FAILED, node=node, name=name)
            if args.action == 'get':
                print(value_text(current[name]))
                return {'ok': True, 'node': node, 'name': name, 'value': current[name]}
            if args.action == 'describe':
                fields = {**client.describe_node_parameter(node, name, args.wait),
                          'name': name, 'value': current[name]}
                print(description_text(fields))
                return {'ok': True, 'node': node, **fields}
            kind, value = typed_value(args.value, current[name])
            try:
                client.set_node_parameter(node, name, value, args.wait, kind)
            except ValueError as exc:
                raise Outcome(str(exc), Exit.FAILED, node=node, name=name,
                              value=value) from None
    finally:
        client.destroy_node()
        rclpy.try_shutdown()
    print(f'{node}: {name} set to {value_text(value)} (was {value_text(current[name])})')
    return {'ok': True, 'node': node, 'name': name, 'value': value, 'previous': current[name]}


def _check_param(args: argparse.Namespace) -> None:
    """A NODE that is a ROS node name (each action's parser takes its own arguments)."""
    if not all(part.isidentifier() for part in args.node.strip('/').split('/')):
        raise usage(f'{args.node!r} is not a ROS node name (letters, digits, _ and / between '
                    'names)')
