"""Declaring parameters in the node shells (rclpy side of :mod:`flexarm_control.params`).

Scalar node settings are declared one by one with a default and a description. Physical
parameter trees (``arm.*``, ``plant.*``, ``camera.*`` ...) come from the ``config/*.yaml``
files: every name under a prefix that the params files set is declared read-only, with a
description pointing at its file, and handed to the core as a nested dict. The names come from
the node's parameter overrides (``Node._parameter_overrides``), the only place rclpy keeps them
before they are declared.
"""
from __future__ import annotations

from typing import Any

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from flexarm_control.params import unflatten


def declare(node: Node, name: str, default: Any, description: str,
            read_only: bool = False) -> Any:
    """Declare one parameter with a descriptor and return its value."""
    descriptor = ParameterDescriptor(description=description, read_only=read_only)
    return node.declare_parameter(name, default, descriptor).value


def declare_tree(node: Node, prefix: str, source: str) -> dict[str, Any]:
    """Declare every parameter ``prefix.*`` given to the node; return them as a nested dict.

    Raises ``ValueError`` naming ``source`` when the params files define none of them.
    """
    names = sorted(n for n in node._parameter_overrides if n.startswith(prefix + '.'))
    if not names:
        raise ValueError(f'no "{prefix}.*" parameters given; pass --params-file {source}')
    flat = {}
    for name in names:
        descriptor = ParameterDescriptor(description=f'see {source}', read_only=True,
                                         dynamic_typing=True)
        value = node.declare_parameter(name, None, descriptor).value
        flat[name[len(prefix) + 1:]] = value
    return unflatten(flat)
