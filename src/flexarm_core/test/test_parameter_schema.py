"""A params file read as the schema of its parameters: defaults and types from the values,
descriptions from the comments (the line's and its continuation, else the block above), the
unit and the range from the description, a node's sections merged over ``/**``."""
from __future__ import annotations

from pathlib import Path

import pytest

from flexarm_core.parameter_schema import file_schema, node_schema

TEXT = '''\
# The file's header: no parameter's.
/**:
  ros__parameters:
    rate: 25.0            # [Hz, sim time] wake-ups a second, range [0.1, 1000.0]
    count: 8              # samples per pose,
                          #   range [1, 100]
    # [m, m, rad] how far the box is grown
    # on every side
    margin: [0.03, 0.03, 0.0436]
    name: "a # not a comment"   # a quoted hash is the value's
    plain: true
    # a block with a blank line below is no parameter's

    undescribed: 1
    arm:                  # a mapping's comment is no leaf's
      # [m] the link
      link: 0.4
      limits:
        hz: [12.41, 11.85,    # [Hz] rows of a table
             3.86, 3.77]      # (rcl takes no nested lists)
      joints:             # the joints, base to tip
        - joint1
        - joint2
/**/flexarm_node:
  ros__parameters:
    rate: 50.0            # [Hz] the node's own rate, range [1.0, 100.0]
    own: ''               # only this node's
'''


def schema(text: str = TEXT) -> dict[str, dict]:
    return file_schema(text, 'test.yaml')


def test_a_trailing_comment_with_its_continuation_is_the_description() -> None:
    rate, count = schema()['/**']['rate'], schema()['/**']['count']
    assert rate.description == '[Hz, sim time] wake-ups a second, range [0.1, 1000.0]'
    assert count.description == 'samples per pose, range [1, 100]'
    assert schema()['/**']['arm.limits.hz'].description == (
        '[Hz] rows of a table (rcl takes no nested lists)')


def test_without_one_the_block_directly_above_is_the_description() -> None:
    section = schema()['/**']
    assert section['margin'].description == '[m, m, rad] how far the box is grown on every side'
    assert section['arm.link'].description == '[m] the link'
    assert section['plain'].description == ''
    assert section['undescribed'].description == ''


def test_the_value_is_the_default_and_gives_the_type() -> None:
    section = schema()['/**']
    assert {name: (spec.default, spec.type) for name, spec in section.items()} == {
        'rate': (25.0, 'double'), 'count': (8, 'integer'),
        'margin': ([0.03, 0.03, 0.0436], 'double_array'),
        'name': ('a # not a comment', 'string'), 'plain': (True, 'bool'),
        'undescribed': (1, 'integer'), 'arm.link': (0.4, 'double'),
        'arm.limits.hz': ([12.41, 11.85, 3.86, 3.77], 'double_array'),
        'arm.joints': (['joint1', 'joint2'], 'string_array')}
    assert section['arm.joints'].description == 'the joints, base to tip'
    assert section['rate'].source == 'test.yaml'


def test_the_unit_and_the_range_come_from_the_description() -> None:
    section = schema()['/**']
    assert (section['rate'].unit, section['rate'].range) == ('Hz, sim time', (0.1, 1000.0))
    assert (section['count'].unit, section['count'].range) == ('', (1, 100))
    assert isinstance(section['count'].range[0], int)
    assert (section['margin'].unit, section['margin'].range) == ('m, m, rad', None)


def test_a_node_gets_its_own_section_over_the_wildcard(tmp_path: Path) -> None:
    path = tmp_path / 'p.yaml'
    path.write_text(TEXT)
    own = node_schema(path, 'flexarm_node')
    assert (own['rate'].default, own['rate'].range) == (50.0, (1.0, 100.0))
    assert own['rate'].description == "[Hz] the node's own rate, range [1.0, 100.0]"
    assert own['count'].default == 8 and own['own'].default == ''
    other = node_schema(path, 'flexarm_other')
    assert other['rate'].default == 25.0 and 'own' not in other


@pytest.mark.parametrize('line, error', [
    ('count: 8   # range [0.5, 10]', 'an integer takes an integer range'),
    ("name: a   # range [0, 1]", 'a string takes no range'),
    ('rate: 1.0   # range [low, high]', 'is no range of numbers'),
    ('mixed: [1, 2.5]', 'is no ROS parameter value'),
    ('empty: []', 'is no ROS parameter value'),
    ('nothing:', 'is no ROS parameter value'),
])
def test_a_value_or_range_ros_cannot_hold_is_refused(line: str, error: str) -> None:
    with pytest.raises(ValueError, match=error):
        schema(f'/**:\n  ros__parameters:\n    {line}\n')
