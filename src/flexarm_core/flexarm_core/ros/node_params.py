"""Declaring parameters in the node shells (rclpy side of :mod:`flexarm_core.parameter_schema`).

Every parameter is declared from the shipped ``config/<file>.yaml`` that holds it, read as its
schema for the node's name: its value there is the default and the type, its comment the
description, its ``range [LOW, HIGH]`` the descriptor's range (rclpy refuses a value outside,
given or set at run time, before the node uses it). So no default is written in code, and a
node started without its params files behaves as the shipped graph does; the params files it
is given supply the values (a site's over the clone's). Which names are writable is the node's
choice, made here: read-only unless the node handles their changes. This module alone calls
rclpy's ``declare_parameter``.
"""
from __future__ import annotations

from collections.abc import Collection
from pathlib import Path
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node

from flexarm_core.parameter_schema import ParameterSpec, node_schema
from flexarm_core.params import config_path, unflatten


def declare(node: Node, name: str, source: str, read_only: bool = False) -> Any:
    """Declare ``name`` as the shipped ``source`` (``config/<file>``) defines it for this
    node, and return its value. ValueError when ``source`` holds no such parameter."""
    spec = schema(node, source).get(name)
    if spec is None:
        raise ValueError(f'{source} defines no parameter {name} for {node.get_name()}')
    return _declared(node, spec, read_only)


def declare_tree(node: Node, prefix: str, source: str,
                 dynamic: Collection[str] = ()) -> dict[str, Any]:
    """Declare every parameter ``prefix.*`` of the shipped ``source`` (``config/<file>``);
    return their values as a nested dict. Names in ``dynamic`` (below ``prefix``) are
    writable, for a node that handles their changes; the rest read-only."""
    below = {name.removeprefix(f'{prefix}.'): spec for name, spec in schema(node, source).items()
             if name.startswith(f'{prefix}.')}
    if not below:
        raise ValueError(f'{source} defines no "{prefix}.*" parameters')
    return unflatten({name: _declared(node, spec, name not in dynamic)
                      for name, spec in below.items()})


def schema(node: Node, source: str) -> dict[str, ParameterSpec]:
    """The parameters the shipped ``source`` defines for this node (by its name)."""
    return node_schema(config_path(Path(source).name), node.get_name())


def _declared(node: Node, spec: ParameterSpec, read_only: bool) -> Any:
    """Declare ``spec`` (its default copied: a node may change the list it is handed)."""
    default = list(spec.default) if isinstance(spec.default, list) else spec.default
    return node.declare_parameter(spec.name, default, descriptor(spec, read_only)).value


def descriptor(spec: ParameterSpec, read_only: bool) -> ParameterDescriptor:
    """The descriptor of ``spec``: its description (unit included) and range."""
    described = ParameterDescriptor(description=spec.description, read_only=read_only)
    if spec.range is not None:
        low, high = spec.range
        if spec.type == 'integer':
            described.integer_range = [IntegerRange(from_value=low, to_value=high, step=1)]
        else:
            described.floating_point_range = [FloatingPointRange(
                from_value=low, to_value=high, step=0.0)]
    return described
