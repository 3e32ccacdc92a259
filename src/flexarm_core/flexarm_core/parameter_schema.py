"""The shipped params files as the schema of every parameter (pure: no rclpy).

A node parameter is written once, in its ``config/<file>.yaml`` (a ROS 2 params file the
launcher passes with ``--params-file``): its value is the default and gives the type (bool,
integer, double, string or an array of one of these), its comment is the description. The
comment is the one on the parameter's line plus the comment-only lines indented deeper below
it, or else, without one, the block of comment lines directly above it at its own indent.
The description's leading ``[...]`` is the unit (``[m]``); ``range [LOW, HIGH]`` in it is the
range the node holds the value to (integers for an integer).

Values come from the YAML loader :mod:`flexarm_core.params` reads the files with, so the
schema and the parameters a node is given never differ; comments from a scan of the lines. A
comment-keeping parser (ruamel.yaml) attaches a comment to the token before it: the block
above one parameter lands on the previous one's line comment, together with that one's
continuation lines, so splitting them by the convention above needs the same line-by-line
reading, and every node would import a second YAML library for it.
"""
from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from flexarm_core.params import SAFE_LOADER, config_path, flatten, load_node_params

SCALAR_TYPES = ((bool, 'bool'), (int, 'integer'), (float, 'double'), (str, 'string'))
PARAMETERS = 'ros__parameters'
KEY = re.compile(r'(?P<indent> *)(?P<key>[^\s#\-\[\]{},][^#]*?)\s*:(?:\s+(?P<value>.*?))?\s*')
QUOTED = re.compile(r'"[^"]*"|\'[^\']*\'')
UNIT = re.compile(r'\[([^\]]*)\]')
RANGE = re.compile(r'\brange \[\s*([^,\]]+?)\s*,\s*([^\]]+?)\s*\]')


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter as its file defines it: ``name`` dotted below the node (``arm.link3``),
    ``type`` as rclpy names it in lower case (``double``, ``string_array``), ``unit`` the
    description's leading ``[...]`` without the brackets, ``source`` the file."""

    name: str
    default: Any
    type: str
    description: str
    unit: str
    range: tuple[int, int] | tuple[float, float] | None
    source: str


@dataclass(frozen=True)
class _Line:
    content: str          # the line without its comment
    comment: str | None   # the comment's text, None without one
    column: int           # where the comment's # is

    @property
    def comment_only(self) -> bool:
        return self.comment is not None and not self.content.strip()


@functools.cache
def node_schema(path: str | Path, node_name: str) -> dict[str, ParameterSpec]:
    """The parameters that ``node_name`` gets from the params file ``path``: ``/**`` merged
    with its own sections, as :func:`flexarm_core.params.load_node_params` merges them. Read
    once a process (a node declares its parameters one by one); not to be changed."""
    sections = _file_sections(str(path))
    winning = ('/' + node_name, node_name, f'/**/{node_name}', '/**')    # first: the last merged
    return {name: next(sections[key][name] for key in winning if name in sections.get(key, {}))
            for name in flatten(load_node_params(path, node_name))}


def file_schema(text: str, source: str) -> dict[str, dict[str, ParameterSpec]]:
    """Section key (``/**``, ``/**/flexarm_vision``) -> its parameters, of a params file's
    ``text``; ValueError for a value that is no ROS parameter or a range that does not fit
    its type."""
    comments = _descriptions(text)
    doc = yaml.load(text, Loader=SAFE_LOADER) or {}
    schema: dict[str, dict[str, ParameterSpec]] = {}
    for key, section in doc.items():
        values = flatten((section or {}).get(PARAMETERS) or {})
        schema[key] = {name: _spec(name, value, comments.get((key, name), ''), source)
                       for name, value in values.items()}
    return schema


def _spec(name: str, value: Any, description: str, source: str) -> ParameterSpec:
    """The parameter ``name`` of ``value`` and comment ``description``."""
    kind = _value_type(value)
    if kind is None:
        raise ValueError(f'{source}: {name}: {value!r} is no ROS parameter value (a bool, '
                         'integer, double, string or a non-empty list of one of these)')
    unit = UNIT.match(description)
    return ParameterSpec(name, value, kind, description, unit.group(1) if unit else '',
                         _range(name, kind, description, source), source)


def _value_type(value: Any) -> str | None:
    """The ROS parameter type of a YAML value (``double``, ``integer_array``); None for one
    that has none (None, a mapping, an empty or mixed list)."""
    if isinstance(value, list):
        kinds = {_scalar_type(item) for item in value}
        return f'{kinds.pop()}_array' if len(kinds) == 1 and None not in kinds else None
    return _scalar_type(value)


def _scalar_type(value: Any) -> str | None:
    return next((kind for python, kind in SCALAR_TYPES if isinstance(value, python)), None)


def _range(name: str, kind: str, description: str, source: str
           ) -> tuple[int, int] | tuple[float, float] | None:
    found = RANGE.search(description)
    if found is None:
        return None
    low, high = found.groups()
    if kind == 'integer':
        if not all(re.fullmatch(r'[-+]?\d+', bound) for bound in (low, high)):
            raise ValueError(f'{source}: {name}: an integer takes an integer range, got '
                             f'{found.group(0)!r}')
        return int(low), int(high)
    if kind != 'double':
        raise ValueError(f'{source}: {name}: a {kind} takes no range')
    try:
        return float(low), float(high)
    except ValueError:
        raise ValueError(f'{source}: {name}: {found.group(0)!r} is no range of numbers'
                         ) from None


@functools.cache
def _file_sections(path: str) -> dict[str, dict[str, ParameterSpec]]:
    """:func:`file_schema` of the file (its source named as config/ names it when it is one
    of config/)."""
    file = Path(path)
    source = (f'config/{file.name}' if file.resolve() == config_path(file.name).resolve()
              else path)
    return file_schema(file.read_text(encoding='utf-8'), source)


def _descriptions(text: str) -> dict[tuple[str, str], str]:
    """(section, dotted name) -> comment of every leaf of a params file's ``text``."""
    lines = [_split(line) for line in text.splitlines()]
    found: dict[tuple[str, str], str] = {}
    stack: list[tuple[int, str]] = []      # the mappings the line is in: indent, key
    i = 0
    while i < len(lines):
        match = KEY.fullmatch(lines[i].content)
        if match is None:
            i += 1
            continue
        indent = len(match['indent'])
        while stack and stack[-1][0] >= indent:
            stack.pop()
        path = [key for _, key in stack] + [match['key'].strip('\'"')]
        end = _value_end(lines, i, match['value'] or '')
        if end is None:
            stack.append((indent, path[-1]))
            i += 1
            continue
        if len(path) > 2 and path[1] == PARAMETERS:
            found[(path[0], '.'.join(path[2:]))] = _comment(lines, i, end, indent)
        i = end + 1
    return found


def _value_end(lines: list[_Line], start: int, value: str) -> int | None:
    """The last line of the value of the key on line ``start`` (a flow list may go on over
    lines, a block list is the ``-`` lines below); None when the key opens a mapping."""
    end = start
    if value:
        depth = _depth(value)
        while depth > 0 and end + 1 < len(lines):
            end += 1
            depth += _depth(lines[end].content)
        return end
    following = [j for j in range(start + 1, len(lines)) if lines[j].content.strip()]
    if not following or not lines[following[0]].content.lstrip().startswith('-'):
        return None
    for j in following:
        if not lines[j].content.lstrip().startswith('-'):
            break
        end = j
    return end


def _comment(lines: list[_Line], start: int, end: int, indent: int) -> str:
    """The comment of the parameter on lines ``start``..``end``: theirs and the comment-only
    lines indented deeper below, else the comment-only lines above at its indent."""
    parts = [line.comment for line in lines[start:end + 1] if line.comment is not None]
    if parts:
        below = end + 1
        while below < len(lines) and lines[below].comment_only and lines[below].column > indent:
            parts.append(lines[below].comment)
            below += 1
    else:
        above = start - 1
        while above >= 0 and lines[above].comment_only and lines[above].column == indent:
            parts.insert(0, lines[above].comment)
            above -= 1
    return ' '.join(part for part in parts if part)


def _split(line: str) -> _Line:
    """A line as content and comment: a ``#`` outside quotes, at the start or after a blank."""
    quote = None
    for i, char in enumerate(line):
        if quote:
            quote = None if char == quote else quote
        elif char in '"\'' and (i == 0 or line[i - 1] in ' [{,:'):
            quote = char
        elif char == '#' and (i == 0 or line[i - 1] in ' \t'):
            return _Line(line[:i].rstrip(), line[i + 1:].strip(), i)
    return _Line(line.rstrip(), None, -1)


def _depth(content: str) -> int:
    """How many flow brackets the content opens (negative: closes)."""
    bare = QUOTED.sub('', content)
    return sum(bare.count(c) for c in '[{') - sum(bare.count(c) for c in ']}')
