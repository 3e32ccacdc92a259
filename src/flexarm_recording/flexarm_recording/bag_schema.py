"""Full ``ros2msg`` schema text of a message type, as rosbag2's MCAP storage writes it.

The text of ``pkg/msg/Type.msg`` is followed by every message type it depends on,
recursively and each once, in rosbag2's format: a line of 80 ``=``, ``MSG: pkg/Type``, then
that type's ``.msg`` text (comments kept). The ``.msg`` files are found in the ament index
layout ``<prefix>/share/<pkg>/msg/<Type>.msg`` of the AMENT_PREFIX_PATH entries and of the
Python environment's prefix (where the ROS wheels install their ``share/``).
"""
from __future__ import annotations

import os
import re
import sys
from collections.abc import Iterable
from functools import cache
from pathlib import Path

SEPARATOR = '=' * 80
PRIMITIVE_TYPES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring'})
_TYPE_NAME = re.compile(r'^([A-Za-z][A-Za-z0-9_]*)/(?:msg/)?([A-Za-z][A-Za-z0-9_]*)$')


def ament_prefixes() -> list[Path]:
    """Install prefixes searched for ``share/<pkg>``: AMENT_PREFIX_PATH, then this Python's."""
    entries = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    entries += [sys.prefix, sys.base_prefix]
    return list(dict.fromkeys(Path(p) for p in entries))


def split_type_name(type_name: str) -> tuple[str, str]:
    """``'pkg/msg/Type'`` or ``'pkg/Type'`` -> ``('pkg', 'Type')``; ValueError otherwise."""
    match = _TYPE_NAME.match(type_name)
    if match is None:
        raise ValueError(f'not a message type name: {type_name!r}')
    return match.group(1), match.group(2)


def find_msg_file(type_name: str, prefixes: Iterable[Path] | None = None) -> Path:
    """Path of the installed ``.msg`` file of a type; FileNotFoundError naming the prefixes."""
    package, name = split_type_name(type_name)
    searched = list(ament_prefixes() if prefixes is None else prefixes)
    for prefix in searched:
        path = prefix / 'share' / package / 'msg' / f'{name}.msg'
        if path.is_file():
            return path
    raise FileNotFoundError(
        f'{package}/msg/{name}.msg not found under share/ of {[str(p) for p in searched]}')


def field_dependencies(msg_text: str, package: str) -> list[str]:
    """Sorted non-primitive field types (``pkg/Type``) of a ``.msg`` text.

    Types without a package refer to the message's own package; array and bound suffixes
    (``[]``, ``[4]``, ``[<=3]``, ``string<=10``) are ignored; constants have primitive types.
    """
    deps = set()
    for line in msg_text.splitlines():
        tokens = line.split('#', 1)[0].split()
        if len(tokens) < 2:
            continue
        field_type = re.split(r'[\[<]', tokens[0], maxsplit=1)[0]
        if field_type in PRIMITIVE_TYPES:
            continue
        dep_package, dep_name = (split_type_name(field_type) if '/' in field_type
                                 else (package, field_type))
        deps.add(f'{dep_package}/{dep_name}')
    return sorted(deps)


@cache
def _msg_text(type_name: str) -> str:
    return find_msg_file(type_name).read_text(encoding='utf-8')


def message_definition(type_name: str) -> str:
    """The full ``ros2msg`` schema text of ``type_name`` with its dependencies appended."""
    package, name = split_type_name(type_name)
    seen: set[str] = set()

    def append(pkg: str, msg: str) -> str:
        text = _msg_text(f'{pkg}/{msg}')
        for dep in field_dependencies(text, pkg):
            if dep not in seen:
                seen.add(dep)
                text += f'\n{SEPARATOR}\nMSG: {dep}\n' + append(*split_type_name(dep))
        return text

    return append(package, name)
