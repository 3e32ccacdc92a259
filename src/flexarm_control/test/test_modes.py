"""One modes enum: its values are the action's constants; labels parse, others are refused."""
import pytest

from flexarm_control.execution.modes import MODE_LABELS, Mode
from flexarm_msgs.action import MoveToPose


def test_modes_are_the_goal_constants():
    assert {m.name: int(m) for m in Mode} == {
        name[len('MODE_'):]: getattr(MoveToPose.Goal, name)
        for name in dir(MoveToPose.Goal) if name.startswith('MODE_')}
    assert MODE_LABELS == ('rigid', 'predictive', 'closed_loop', 'auto')


def test_labels_and_numbers_parse_and_unknown_ones_are_named():
    assert Mode.of('closed_loop') is Mode.CLOSED_LOOP and Mode.of(1) is Mode.PREDICTIVE
    assert Mode.of(Mode.RIGID) is Mode.RIGID
    with pytest.raises(ValueError, match="unknown mode 'teleport'; use one of rigid, "):
        Mode.of('teleport')
