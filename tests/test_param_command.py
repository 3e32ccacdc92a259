"""Node-level: `flexarm param get|set|list|describe` over a node's parameter services, as ros2
param does (rclpy from PyPI has no ros2 CLI); a refused set says the node's reason, a described
parameter its shipped file's description and range. The vision node's tool correction, set
so, moves the calibrated camera frame it publishes on /tf_static. One vision node serves the
module's tests; each leaves its parameters as it found them."""
from __future__ import annotations

import json
import math
from typing import Any

import pytest

from flexarm_cli import main
from flexarm_core import liveness, topics
from flexarm_core.frames import CALIBRATED_CAMERA_FRAME
from flexarm_core.parameter_schema import node_schema
from flexarm_core.params import config_path, load_config
from flexarm_core.tool_correction import ToolCorrection
from flexarm_recording.results.outcome_text import Exit
from flexarm_test_support.tf_listening import STATIC_TF_QOS
from tf2_msgs.msg import TFMessage

pytestmark = pytest.mark.node
NODE = 'flexarm_vision'
OFFSET = load_config('camera.yaml')['camera']['offset']
WAIT = 30.0     # [s, liveness-scaled] for the node's parameter services


@pytest.fixture(scope='module', autouse=True)
def vision(module_launch: Any, tmp_path_factory: pytest.TempPathFactory) -> Any:
    folder = tmp_path_factory.mktemp('calibration')    # no calibration: neutral corrections
    return module_launch(NODE, tool_calibration_file=str(folder / 'tool_camera.json'),
                         camera_calibration_file=str(folder / 'camera.json'))


def param(capsys: Any, *args: str) -> tuple[int, str, str, dict[str, Any]]:
    """``flexarm --json param ARGS``: exit code, its words on stdout and stderr, its JSON."""
    code = main(['--json', 'param', *args, '--wait', str(liveness.limit(WAIT))])
    out, err = capsys.readouterr()
    *words, last = out.splitlines()
    return code, '\n'.join(words), err, json.loads(last)


def test_list_and_get_show_the_nodes_parameters(capsys) -> None:
    code, words, _, result = param(capsys, 'list', NODE)
    assert code == Exit.OK
    assert 'tool_correction: [0.0, 0.0, 0.0]' in words.splitlines()
    assert result['parameters']['camera.offset'] == OFFSET
    code, words, _, result = param(capsys, 'list', NODE, 'camera.')
    assert code == Exit.OK and result['parameters']
    assert all(name.startswith('camera.') for name in result['parameters'])
    code, words, _, result = param(capsys, 'get', NODE, 'camera.offset')
    assert (code, result['value']) == (Exit.OK, OFFSET)
    assert words == f'[{OFFSET[0]}, {OFFSET[1]}]'


def test_set_changes_the_value_and_the_calibrated_camera_frame(capsys, ros_node: Any,
                                                                 wait_for: Any) -> None:
    frames: list[Any] = []
    ros_node.create_subscription(
        TFMessage, topics.TF_STATIC, lambda m: frames.extend(
            t for t in m.transforms if t.child_frame_id == CALIBRATED_CAMERA_FRAME),
        STATIC_TF_QOS)

    def mount_at(correction: ToolCorrection) -> Any:
        along, across, _ = correction.camera_mount(OFFSET)
        return next((t for t in reversed(frames) if math.isclose(
            t.transform.translation.x, along, abs_tol=1e-12) and math.isclose(
            t.transform.translation.z, across, abs_tol=1e-12)), None)

    wait_for(lambda: mount_at(ToolCorrection()), 10.0, 'the neutral calibrated camera frame')
    try:
        code, words, _, result = param(capsys, 'set', NODE, 'tool_correction', '[0, 0.001, 0]')
        assert code == Exit.OK, result
        assert words == f'{NODE}: tool_correction set to [0.0, 0.001, 0.0] (was [0.0, 0.0, 0.0])'
        assert param(capsys, 'get', NODE, 'tool_correction')[3]['value'] == [0.0, 0.001, 0.0]
        wait_for(lambda: mount_at(ToolCorrection(lateral=0.001)), 10.0,
                 'the calibrated camera frame moved by the new correction')
    finally:
        assert param(capsys, 'set', NODE, 'tool_correction', '[0, 0, 0]')[0] == Exit.OK


@pytest.mark.parametrize('name, value, reason', [
    ('tool_correction', '[1, 2]', 'a tool correction is 3 finite values [m, m, rad], got '
                                  '[1.0, 2.0]'),
    ('camera.fx', '500', 'Trying to set a read-only parameter: camera.fx.'),
])
def test_a_refused_set_says_the_nodes_reason(capsys, name, value, reason) -> None:
    before = param(capsys, 'get', NODE, name)[3]['value']
    code, _, err, result = param(capsys, 'set', NODE, name, value)
    assert code == Exit.FAILED
    assert f'flexarm param: {NODE} refused {name}: {reason}' in err, err
    assert not result['ok']
    assert param(capsys, 'get', NODE, name)[3]['value'] == before


def test_describe_says_the_shipped_description_range_and_value(capsys) -> None:
    shipped = node_schema(config_path('vision.yaml'), NODE)['vision.threshold']
    code, words, _, result = param(capsys, 'describe', NODE, 'vision.threshold')
    assert code == Exit.OK
    assert result == {
        'ok': True, 'exit_code': 0, 'node': NODE, 'name': 'vision.threshold', 'type': 'double',
        'description': shipped.description, 'range': [0.0, 1.0], 'read_only': True,
        'value': shipped.default}
    assert 'segment pixels darker than 50 % of the plate level' in shipped.description
    assert words.splitlines() == [
        'vision.threshold', '  type: double', f'  description: {shipped.description}',
        '  range: [0.0, 1.0]', '  read-only: true', f'  value: {shipped.default}']
    code, _, _, result = param(capsys, 'describe', NODE, 'tool_correction')
    assert (code, result['type'], result['range'], result['read_only']) == (
        Exit.OK, 'double_array', None, False)
    assert result['description'].startswith("[m, m, rad] the camera's error in the tool frame")


@pytest.mark.parametrize('action', ['get', 'describe'])
def test_a_parameter_the_node_lacks_is_named(capsys, action) -> None:
    code, _, err, _ = param(capsys, action, NODE, 'no_such_parameter')
    assert code == Exit.FAILED
    assert f'{NODE} has no parameter no_such_parameter' in err
