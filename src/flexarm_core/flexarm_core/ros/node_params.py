"""Declaring parameters in the node shells (rclpy side of :mod:`flexarm_core.params`).

Scalar node settings are declared one by one with a default, a description and, for a number
with a meaningful range, its bounds (the descriptor's range: rclpy refuses a value outside).
Physical parameter trees (``arm.*``, ``plant.*``, ``camera.*`` ...) come from the ``config/*.yaml``
files: the shipped file is the tree's schema (which names exist), the params files the node
was given supply the values. Every name is declared with a description pointing at its file,
read-only unless the node handles its changes, and handed to the core as a nested dict; a name
the node was not given is an error naming the file to pass. (rclpy has no public list of the
overrides a node was given.)
"""
from __future__ import annotations

from collections.abc import Collection
from pathlib import Path
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node

from flexarm_core.params import config_path, flatten, load_node_params, unflatten


def declare(node: Node, name: str, default: Any, description: str,
            read_only: bool = False, bounds: tuple[float, float] | None = None) -> Any:
    """Declare one parameter with a descriptor and return its value. ``bounds`` (low, high):
    the range rclpy holds it to, given or set at run time (a value outside is refused with
    the range, before the node uses it); integer for an integer default."""
    descriptor = ParameterDescriptor(description=description, read_only=read_only)
    if bounds is not None:
        low, high = bounds
        if isinstance(default, bool) or not isinstance(default, (int, float)):
            raise TypeError(f'{name}: bounds need a numeric default, got {default!r}')
        if isinstance(default, int):
            descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high),
                                                     step=1)]
        else:
            descriptor.floating_point_range = [FloatingPointRange(
                from_value=float(low), to_value=float(high), step=0.0)]
    return node.declare_parameter(name, default, descriptor).value


def declare_tree(node: Node, prefix: str, source: str,
                 dynamic: Collection[str] = ()) -> dict[str, Any]:
    """Declare every parameter ``prefix.*`` of the shipped ``source`` (``config/<file>``);
    return the values the node was given as a nested dict. Names in ``dynamic`` (below
    ``prefix``) are writable, for a node that handles their changes; the rest read-only.

    Raises ``ValueError`` naming ``source`` when the node was not given one of them.
    """
    schema = load_node_params(config_path(Path(source).name), node.get_name()).get(prefix)
    if not isinstance(schema, dict) or not schema:
        raise ValueError(f'{source} defines no "{prefix}.*" parameters')
    flat, missing = {}, []
    for name in flatten(schema):
        descriptor = ParameterDescriptor(description=f'see {source}',
                                         read_only=name not in dynamic, dynamic_typing=True)
        flat[name] = node.declare_parameter(f'{prefix}.{name}', None, descriptor).value
        if flat[name] is None:
            missing.append(f'{prefix}.{name}')
    if missing:
        raise ValueError(f'{len(missing)} "{prefix}.*" parameter(s) not given (e.g. '
                         f'{missing[0]}); pass --params-file {source}')
    return unflatten(flat)
