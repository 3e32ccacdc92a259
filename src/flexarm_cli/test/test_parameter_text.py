"""Values typed for `flexarm param set` are read as `ros2 param set` reads them, except that a
number sets a double parameter as a double."""
from __future__ import annotations

import pytest
from rclpy.parameter import Parameter

from flexarm_cli.parameter_text import description_text, typed_value, value_text

Kind = Parameter.Type


@pytest.mark.parametrize('text, kind, value', [
    ('true', Kind.BOOL, True), ('2', Kind.INTEGER, 2), ('2.5', Kind.DOUBLE, 2.5),
    ('-1.0e-3', Kind.DOUBLE, -1e-3), ('flexarm_recorder', Kind.STRING, 'flexarm_recorder'),
    ("'7'", Kind.STRING, '7'), ('[true, false]', Kind.BOOL_ARRAY, [True, False]),
    ('[1, 2]', Kind.INTEGER_ARRAY, [1, 2]), ('[0.5, 1.5]', Kind.DOUBLE_ARRAY, [0.5, 1.5]),
    ('[a, b]', Kind.STRING_ARRAY, ['a', 'b']), ('[]', Kind.BOOL_ARRAY, []),
    ('[1, 2.5]', Kind.STRING, '[1, 2.5]'), ('{a: 1}', Kind.STRING, '{a: 1}'),
    ('[1, [2]]', Kind.STRING, '[1, [2]]'), ('', Kind.STRING, ''),
    ('a: b: c', Kind.STRING, 'a: b: c'),
])
def test_as_ros2_param_set_reads_it(text, kind, value) -> None:
    assert typed_value(text) == (kind, value)
    assert typed_value(text, current='text') == (kind, value)


def test_whole_numbers_set_a_double_parameter_as_doubles() -> None:
    assert typed_value('2', current=0.5) == (Kind.DOUBLE, 2.0)
    assert typed_value('[0, 0.001, 0]', current=[0.0, 0.0, 0.0]) == (
        Kind.DOUBLE_ARRAY, [0.0, 0.001, 0.0])
    assert typed_value('[]', current=[0.0]) == (Kind.DOUBLE_ARRAY, [])
    assert typed_value('[]', current=['a']) == (Kind.STRING_ARRAY, [])
    assert typed_value('2', current=3) == (Kind.INTEGER, 2)
    assert typed_value('true', current=0.5) == (Kind.BOOL, True)   # the node says no


@pytest.mark.parametrize('value', [True, 3, 0.25, -1e-9, 'flexarm_recorder',
                                   [0.0, 0.001, -2.5], ['a', 'b c'], [1, 2], [False]])
def test_a_value_shown_reads_back_as_itself(value) -> None:
    kind, read = typed_value(value_text(value), current=value)
    assert read == value and type(read) is type(value)


def test_a_description_is_a_line_a_field() -> None:
    fields = {'name': 'port', 'type': 'integer', 'description': 'TCP port, range [1, 65535]',
              'range': [1, 65535], 'read_only': False, 'value': 47800}
    assert description_text(fields).splitlines() == [
        'port', '  type: integer', '  description: TCP port, range [1, 65535]',
        '  range: [1, 65535]', '  read-only: false', '  value: 47800']
    unbounded = description_text({**fields, 'range': None, 'description': ''})
    assert '  range: none' in unbounded and '  description: (none)' in unbounded
