"""Read ROS 2 parameter files (``node: ros__parameters: {...}``) without rclpy.

Core modules are configured from plain nested dicts; nodes get the same dicts from their
declared parameters (dotted names), tests and benchmarks get them from the YAML files here.
"""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from flexarm_core.paths import CONFIG_DIR, SITE_CONFIG_DIR

# libyaml's parser (PyYAML's wheels carry it) reads config/ some 8 times faster than the pure
# Python one: every node process and command reads several files as it starts.
SAFE_LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)


def config_path(name: str) -> Path:
    """``config/<name>``: the clone's, else the installed one (see flexarm_core.paths)."""
    return CONFIG_DIR / name


def config_layers(name: str) -> list[Path]:
    """The files of ``config/<name>``, later ones winning parameter by parameter: the clone's,
    then the site's if it has one (:mod:`flexarm_core.paths`). A node gets them as that many
    ``--params-file`` arguments, in this order, as ROS layers params files."""
    site = SITE_CONFIG_DIR / name if SITE_CONFIG_DIR else None
    return [config_path(name), *([site] if site and site.is_file() else [])]


def load_node_params(path: str | Path, node_name: str) -> dict[str, Any]:
    """Parameters that ``node_name`` gets from a params file: ``/**`` merged with its own
    (``/**/<node_name>``, the key the files use so that it holds in any namespace, or
    ``<node_name>``)."""
    with open(path, encoding='utf-8') as f:
        doc = yaml.load(f, Loader=SAFE_LOADER) or {}
    merged: dict[str, Any] = {}
    for key in ('/**', f'/**/{node_name}', node_name, '/' + node_name):
        section = doc.get(key) or {}
        _deep_update(merged, section.get('ros__parameters') or {})
    return merged


def load_config(*names: str, node_name: str = '/**') -> dict[str, Any]:
    """Merge the parameters of several ``config/`` files (each with its site layer, see
    :func:`config_layers`), later files winning."""
    merged: dict[str, Any] = {}
    for name in names:
        for path in config_layers(name):
            _deep_update(merged, load_node_params(path, node_name))
    return merged


def flatten(tree: Mapping[str, Any], prefix: str = '') -> dict[str, Any]:
    """Nested dict -> ROS dotted parameter names (the inverse of :func:`unflatten`)."""
    flat: dict[str, Any] = {}
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, Mapping):
            flat.update(flatten(value, name + '.'))
        else:
            flat[name] = value
    return flat


def unflatten(flat: Mapping[str, Any]) -> dict[str, Any]:
    """ROS dotted parameter names -> nested dict (``{'a.b': 1}`` -> ``{'a': {'b': 1}}``)."""
    tree: dict[str, Any] = {}
    for name, value in flat.items():
        node = tree
        *parents, leaf = name.split('.')
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    return tree


def _deep_update(target: dict[str, Any], source: Mapping[str, Any]) -> None:
    for key, value in source.items():
        if isinstance(value, Mapping) and isinstance(target.get(key), dict):
            _deep_update(target[key], value)
        else:
            target[key] = dict(value) if isinstance(value, Mapping) else value
