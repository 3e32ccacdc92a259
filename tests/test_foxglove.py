"""Live view in Foxglove: the channels the server offers, to clients offering either name of
the protocol, the shipped layout, the `flexarm up --foxglove` flag, and (node level) `flexarm up
--foxglove PORT` serving /tip_pose to a WebSocket client of the Foxglove protocol."""
from __future__ import annotations

import json
import math
import os
import shutil
import signal
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from rclpy.serialization import deserialize_message, serialize_message
from websockets.exceptions import InvalidStatus
from websockets.sync.client import ClientConnection, connect

from flexarm_bringup.launcher import node_name
from flexarm_cli import build_parser, main
from flexarm_cli.graph import foxglove_text
from flexarm_core import liveness, topics
from flexarm_core.frames import PLANE_FRAME
from flexarm_core.params import config_path, load_config
from flexarm_core.paths import RUNS_DIR
from flexarm_msgs.msg import PlanarPose, TipPose
from flexarm_recording.bag_schema import message_definition
from flexarm_recording.results.outcome_text import Exit

pytestmark = [pytest.mark.node, pytest.mark.duration(15)]

SDK_NAME = 'foxglove.sdk.v1'
FORMER_NAME = 'foxglove.websocket.v1'    # the only one Lichtblick <= 1.22.0 offers
MESSAGE_DATA = 1          # opcode of a binary message data frame
TIP_POSE_TYPE = 'flexarm_msgs/msg/TipPose'
# The graph's names (flexarm_core.topics): what a layout may name.
# The graph's names as a viewer sees a graph without namespace: the constants in full.
GRAPH_NAMES = {topics.absolute(v) for k, v in vars(topics).items()
               if k.isupper() and isinstance(v, str)}
UP_TIMEOUT = 90           # [s] `flexarm up --timeout`: its own bound on the graph's start
# [s, liveness-scaled] of up's bounds after the graph is ready (first reports, the model, the
# calibration, the Foxglove node's announcement: cli/graph.py's waits, 21 s in all)
UP_AFTER_READY = 30.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def _client(port: int, subprotocols: list[str]) -> ClientConnection:
    return connect(f'ws://127.0.0.1:{port}', subprotocols=subprotocols, open_timeout=10.0,
                   max_size=None)


@pytest.fixture
def served() -> Iterator[tuple[Any, int]]:
    """(SDK context, port of the front) of an SDK server behind a front, as the node has."""
    import foxglove

    from flexarm_viz.foxglove_front import SubprotocolFront

    context = foxglove.Context()
    server = foxglove.start_server(host='127.0.0.1', port=0, context=context)
    front = SubprotocolFront('127.0.0.1', 0, server.port)
    try:
        yield context, front.port
    finally:
        front.stop()
        server.stop()


def _advertised(ws: ClientConnection, topic: str, timeout: float) -> dict[str, Any]:
    """The channel of ``topic`` once the server has advertised it."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        frame = ws.recv(timeout=max(deadline - time.monotonic(), 0.01))
        if isinstance(frame, str):
            message = json.loads(frame)
            for channel in message.get('channels', []) if message['op'] == 'advertise' else []:
                if channel['topic'] == topic:
                    return channel
    pytest.fail(f'{topic} not advertised within {timeout} s')


def _message_data(ws: ClientConnection, channel_id: int, timeout: float) -> tuple[int, bytes]:
    """Subscribe to a channel; (log time [ns], payload) of its first message data frame."""
    ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [{'id': 7,
                                                               'channelId': channel_id}]}))
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        frame = ws.recv(timeout=max(deadline - time.monotonic(), 0.01))
        if isinstance(frame, bytes) and frame[0] == MESSAGE_DATA:
            _, subscription, log_time = struct.unpack_from('<BIQ', frame)
            assert subscription == 7
            return log_time, frame[13:]
    pytest.fail(f'no message on channel {channel_id} within {timeout} s')


def _first_message(ws: ClientConnection, channel: Any, advertised: dict[str, Any],
                   sent: bytes) -> bytes:
    """Subscribe to the advertised channel, log ``sent`` on it once subscribed; the frame."""
    ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
        {'id': 7, 'channelId': advertised['id']}]}))
    deadline = time.monotonic() + 5.0
    while not channel.has_sinks() and time.monotonic() < deadline:
        time.sleep(0.01)
    channel.log(sent, log_time=123)
    while isinstance(frame := ws.recv(timeout=5.0), str):
        pass
    return frame


@pytest.mark.parametrize(('offer', 'agreed'), [
    ([FORMER_NAME], FORMER_NAME), ([SDK_NAME], SDK_NAME),
    ([FORMER_NAME, SDK_NAME], SDK_NAME), ([SDK_NAME, FORMER_NAME], SDK_NAME)])
def test_a_channel_carries_cdr_with_the_full_ros2msg_schema_to_either_name(
        served: tuple[Any, int], offer: list[str], agreed: str) -> None:
    from flexarm_viz.foxglove_node import ros2_channel

    context, port = served
    channel = ros2_channel(topics.absolute(topics.TIP_POSE), TIP_POSE_TYPE, context)
    sent = serialize_message(TipPose(pose=PlanarPose(x=1.45, y=-0.15), valid=True))
    with _client(port, offer) as ws:
        assert ws.subprotocol == agreed
        assert json.loads(ws.recv(timeout=5.0))['op'] == 'serverInfo'
        advertised = _advertised(ws, topics.absolute(topics.TIP_POSE), 5.0)
        assert (advertised['encoding'], advertised['schemaName'],
                advertised['schemaEncoding']) == ('cdr', TIP_POSE_TYPE, 'ros2msg')
        assert advertised['schema'] == message_definition(TIP_POSE_TYPE)
        assert 'MSG: flexarm_msgs/PlanarPose' in advertised['schema']
        frame = _first_message(ws, channel, advertised, sent)
    assert frame[0] == MESSAGE_DATA and struct.unpack_from('<IQ', frame, 1) == (7, 123)
    assert frame[13:] == sent


def test_a_camera_sized_message_passes_the_front_whole(served: tuple[Any, int]) -> None:
    from flexarm_viz.foxglove_node import ros2_channel

    context, port = served
    channel = ros2_channel(topics.absolute(topics.CAMERA_IMAGE), 'sensor_msgs/msg/Image',
                           context)
    sent = os.urandom(3 * 1024 * 1024)
    with _client(port, [FORMER_NAME]) as ws:
        advertised = _advertised(ws, topics.absolute(topics.CAMERA_IMAGE), 5.0)
        assert _first_message(ws, channel, advertised, sent)[13:] == sent


@pytest.mark.parametrize('offer', [None, ['foxglove.websocket.v2']])
def test_other_offers_get_the_sdks_refusal(served: tuple[Any, int],
                                           offer: list[str] | None) -> None:
    with pytest.raises(InvalidStatus) as refused:
        _client(served[1], offer)
    assert refused.value.response.status_code == 400
    assert b'sec-websocket-protocol' in refused.value.response.body


def test_the_sdk_itself_still_refuses_the_former_name() -> None:
    """The reason for the front: once this fails, the SDK accepts the former name itself."""
    import foxglove

    server = foxglove.start_server(host='127.0.0.1', port=0, context=foxglove.Context())
    try:
        with pytest.raises(InvalidStatus) as refused:
            _client(server.port, [FORMER_NAME])
        with _client(server.port, [SDK_NAME]) as ws:
            assert ws.subprotocol == SDK_NAME
    finally:
        server.stop()
    assert refused.value.response.status_code == 400


def test_the_front_listens_once_made_and_the_node_says_so_for_its_own_process() -> None:
    """What up waits for before it says where to connect: the node's line, logged once the
    SDK's server and the front are made (each listens when made), naming its process."""
    from flexarm_viz.foxglove_front import SubprotocolFront
    from flexarm_viz.foxglove_node import announcement, listening_url

    front = SubprotocolFront('127.0.0.1', 0, _free_port())
    try:
        socket.create_connection(('127.0.0.1', front.port), timeout=1.0).close()
    finally:
        front.stop()
    log = ('[INFO] [1.0] [flexarm_foxglove]: ' + announcement('ws://127.0.0.1:8765', 41)
           + ", serving ['*'] (images: False)\n[INFO] [2.0] [flexarm_foxglove]: serving /x\n")
    assert listening_url(log, 41) == 'ws://127.0.0.1:8765'
    assert listening_url(log, 4) is None and listening_url(log, 411) is None   # another run
    assert listening_url('', 41) is None


class _NodeLog:
    """A stand-in of a running node's process and log for up's wait (a NodeProcess)."""

    def __init__(self, log_path: Path, pid: int) -> None:
        from types import SimpleNamespace

        self.log_path, self.returncode = log_path, None
        self.process = SimpleNamespace(pid=pid)
        self.spec = SimpleNamespace(name='flexarm_foxglove')


def test_up_says_where_to_connect_only_once_the_node_said_it_listens(tmp_path: Path) -> None:
    import threading

    from flexarm_cli.graph import foxglove_served
    from flexarm_viz.foxglove_node import announcement

    node = _NodeLog(tmp_path / 'flexarm_foxglove.log', 41)
    node.log_path.write_text(f'{announcement("ws://127.0.0.1:1", 40)}\n')   # its predecessor
    said = threading.Timer(0.3, lambda: node.log_path.write_text(
        f'{announcement("ws://127.0.0.1:9001", 41)}, serving [] (images: False)\n'))
    said.start()
    started = time.monotonic()
    text = foxglove_served(node, within=30.0)
    assert time.monotonic() - started >= 0.25
    assert text.startswith('Foxglove: open a connection to ws://127.0.0.1:9001 ')
    node.returncode = 1
    node.log_path.write_text('')
    assert foxglove_served(node, within=30.0).startswith(
        'Foxglove: not served: flexarm_foxglove exited')


def test_unknown_types_have_no_channel() -> None:
    import foxglove

    from flexarm_viz.foxglove_node import ros2_channel

    with pytest.raises(FileNotFoundError):
        ros2_channel('/x', 'no_such_msgs/msg/Thing', foxglove.Context())


def _panels(layout: Any) -> Iterator[str]:
    """Panel ids of a layout tree (a panel id, or a split of two trees)."""
    if isinstance(layout, str):
        yield layout
    else:
        yield from _panels(layout['first'])
        yield from _panels(layout['second'])


def test_layout_opens_the_graphs_topics_in_its_four_panels() -> None:
    layout = json.loads(config_path('foxglove_layout.json').read_text(encoding='utf-8'))
    panels = layout['configById']
    assert sorted(_panels(layout['layout'])) == sorted(panels)
    by_type = {panel_id.split('!')[0]: config for panel_id, config in panels.items()}
    assert set(by_type) == {'3D', 'Plot', 'Image', 'DiagnosticSummary'}

    three_d = by_type['3D']
    assert three_d['followTf'] == 'base_link'
    [urdf] = [layer for layer in three_d['layers'].values()
              if layer['layerId'] == 'foxglove.Urdf']
    description = topics.absolute(topics.ROBOT_DESCRIPTION)
    assert (urdf['sourceType'], urdf['topic']) == ('topic', description)
    assert {topics.absolute(t) for t in (topics.TF, topics.TF_STATIC, topics.SCENE_MARKERS)
            } <= set(three_d['topics'])
    plotted = {path['value'].split('.')[0] for path in by_type['Plot']['paths']}
    assert plotted == {topics.absolute(topics.OUTCOMES)}
    assert 'position_error' in by_type['Plot']['paths'][0]['value']
    assert by_type['Image']['imageMode']['imageTopic'] == topics.absolute(topics.CAMERA_IMAGE)
    assert by_type['DiagnosticSummary']['topicToRender'] == topics.DIAGNOSTICS

    named = {*three_d['topics'], urdf['topic'], *plotted,
             by_type['Image']['imageMode']['imageTopic'],
             by_type['DiagnosticSummary']['topicToRender']}
    assert named <= GRAPH_NAMES, named - GRAPH_NAMES


def test_foxglove_flag_port_defaults_to_the_config_and_is_checked(capsys) -> None:
    parse = build_parser().parse_args
    assert parse(['up']).foxglove is None
    assert parse(['up', '--foxglove']).foxglove == 0          # the node's configured port
    assert parse(['up', '--foxglove', '9001', '--rtf', '2']).foxglove == 9001
    config = load_config('foxglove.yaml', node_name=node_name('foxglove'))
    assert (config['host'], config['port']) == ('127.0.0.1', 8765)
    assert 'ws://127.0.0.1:9001 ' in foxglove_text('ws://127.0.0.1:9001')
    assert 'foxglove_layout.json' in foxglove_text('ws://127.0.0.1:9001')
    assert main(['up', '--foxglove', '70000']) == Exit.USAGE
    assert 'must be a TCP port 1..65535' in capsys.readouterr().err


def _served(ros_node: Any, topic: str) -> bool:
    """Whether the Foxglove node subscribes to ``topic``."""
    return any(s.node_name == 'flexarm_foxglove'
               for s in ros_node.get_subscriptions_info_by_topic(topic))


@pytest.mark.node
def test_up_with_foxglove_serves_tip_pose_to_a_websocket_client(
        domain_id: int, tmp_path: Path, ros_node: Any, wait_for: Any) -> None:
    """Also: the node subscribes to a topic only while a client watches its channel."""
    port, name = _free_port(), f'test-foxglove-{domain_id}-{os.getpid()}'
    log_path = tmp_path / 'up.log'
    with open(log_path, 'wb') as log:
        up = subprocess.Popen(
            [sys.executable, '-m', 'flexarm_cli', 'up', '--foxglove', str(port),
             '--domain-id', str(domain_id), '--name', name, '--timeout', str(UP_TIMEOUT)],
            stdout=log, stderr=subprocess.STDOUT, env={**os.environ, 'PYTHONUNBUFFERED': '1'})
    try:
        # up says where to connect once the node has said its server listens (an event);
        # up bounds every wait before it, so this bound only catches an up that hangs
        deadline = time.monotonic() + UP_TIMEOUT + liveness.limit(UP_AFTER_READY)
        while 'Foxglove: ' not in log_path.read_text(errors='replace'):
            if up.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f'flexarm up did not get ready: {log_path.read_text()}')
            time.sleep(0.1)
        assert f'Foxglove: open a connection to ws://127.0.0.1:{port} ' in log_path.read_text()
        with _client(port, [FORMER_NAME]) as ws:
            assert ws.subprotocol == FORMER_NAME
            channel = _advertised(ws, topics.absolute(topics.TIP_POSE), 30.0)
            assert (channel['encoding'], channel['schemaName']) == ('cdr', TIP_POSE_TYPE)
            assert not _served(ros_node, topics.TIP_POSE)
            log_time, payload = _message_data(ws, channel['id'], 30.0)
            wait_for(lambda: _served(ros_node, topics.TIP_POSE), 10.0,
                     'the graph to show the Foxglove node subscribed to /tip_pose')
        wait_for(lambda: not _served(ros_node, topics.TIP_POSE), 10.0,
                 'the Foxglove node to unsubscribe once its client left')
    finally:
        up.send_signal(signal.SIGINT)
        try:
            code = up.wait(timeout=30.0)
        except subprocess.TimeoutExpired:
            up.kill()
            code = up.wait(timeout=10.0)
        shutil.rmtree(RUNS_DIR / name, ignore_errors=True)
    assert code == 0, log_path.read_text()
    tip = deserialize_message(payload, TipPose)
    assert tip.header.frame_id == PLANE_FRAME
    assert abs(log_time - time.time_ns()) < 120 * 10**9
    if tip.valid:
        assert 0.3 < tip.pose.x < 3.0 and math.isfinite(tip.pose.phi)
