"""Parameter values as the command line types and shows them, and a parameter's description
(``flexarm param``).

A value typed is read as ``ros2 param set`` reads it: YAML; a bool, an integer, a double or a
string, or a flat list all of one of these kinds; anything else (a mapping, a mixed list, text
YAML cannot parse) is the text itself, as a string. One difference, so that a number sets a
double parameter as a user means it: where the parameter holds a double (or a list of
doubles) now, whole numbers are sent as doubles (``ros2 param set`` sends ``1`` as an integer,
which the node refuses: the type of a declared parameter does not change), and an empty list
takes the current list's kind (``ros2 param set`` sends a list of bools).
"""
from __future__ import annotations

from typing import Any

import yaml
from rclpy.parameter import Parameter

Kind = Parameter.Type
_SCALARS = ((bool, Kind.BOOL, Kind.BOOL_ARRAY), (int, Kind.INTEGER, Kind.INTEGER_ARRAY),
            (float, Kind.DOUBLE, Kind.DOUBLE_ARRAY), (str, Kind.STRING, Kind.STRING_ARRAY))


def typed_value(text: str, current: Any = None) -> tuple[Parameter.Type, Any]:
    """The kind and value ``text`` sets, for a parameter whose value is ``current`` now."""
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        return Kind.STRING, text
    doubles = isinstance(current, float) or (
        isinstance(current, list) and bool(current) and _kind(current[0]) is float)
    if isinstance(value, list):
        if not value:
            return (_array_kind(current[0]) if isinstance(current, list) and current
                    else Kind.BOOL_ARRAY), []
        if doubles and all(_kind(v) in (int, float) for v in value):
            return Kind.DOUBLE_ARRAY, [float(v) for v in value]
        kinds = {_kind(v) for v in value}
        if len(kinds) == 1 and None not in kinds:
            return _array_kind(value[0]), value
        return Kind.STRING, text
    kind = _kind(value)
    if kind is int and doubles:
        return Kind.DOUBLE, float(value)
    if kind is None:
        return Kind.STRING, text
    return next(scalar for python, scalar, _ in _SCALARS if python is kind), value


def value_text(value: Any) -> str:
    """A parameter's value as typed back (:func:`typed_value` reads it as the same value)."""
    if isinstance(value, str):
        return value
    return yaml.safe_dump(value, default_flow_style=True, width=1 << 30).removesuffix(
        '\n...\n').strip()


def description_text(fields: dict[str, Any]) -> str:
    """What ``flexarm param describe`` says of a parameter, a line each: its name, type,
    description, range, whether it is read-only, and its value."""
    low_high = fields['range']
    return '\n'.join([
        fields['name'], f"  type: {fields['type']}",
        f"  description: {fields['description'] or '(none)'}",
        f"  range: {value_text(low_high) if low_high else 'none'}",
        f"  read-only: {value_text(fields['read_only'])}",
        f"  value: {value_text(fields['value'])}"])


def _kind(value: Any) -> type | None:
    """bool, int, float or str: the parameter kind of a YAML value; None for another."""
    return next((python for python, _, _ in _SCALARS if isinstance(value, python)), None)


def _array_kind(element: Any) -> Parameter.Type:
    return next(array for python, _, array in _SCALARS if python is _kind(element))
