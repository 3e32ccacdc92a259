"""Node-level: one motion at a time per arm. While a collection, a move or a calibration holds
the arm, every other motion — from another client, to another node — is refused before
anything moves, with the running motion named; samples record the motion they were taken in;
``flexarm cancel`` ends a calibration between its poses; a holder that dies frees the arm.

One graph for the module (simulator at real time: a move to B4 takes some 3 s, time enough
to send a second motion meanwhile), two clients of their own.
"""
from __future__ import annotations

import math
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
import rclpy
from rclpy.context import Context
from rclpy.qos import QoSDurabilityPolicy, QoSProfile

from flexarm_cli.calibration import calibrate_tool
from flexarm_control.ros.client import FlexarmClient
from flexarm_core import liveness, topics
from flexarm_deflection.dataset import load_dataset
from flexarm_motion.ros.arm_claim import ArmBusy
from flexarm_msgs.action import CollectSamples, MoveToPose, RefreshModel
from flexarm_msgs.msg import ArmMotion

pytestmark = [pytest.mark.node, pytest.mark.duration(35)]

B4 = (1.0, -0.5, math.radians(-100))      # Table 10 B4: seconds away from the start pose
A1 = (1.4, -0.2, math.radians(-5))
LATCHED = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)


@pytest.fixture(scope='module')
def graph(module_launch, tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp('arm_owner')
    module_launch('flexarm_sim', real_time_factor=1.0, error_sources={'enabled': False})
    module_launch('flexarm_vision')
    module_launch('flexarm_learner', data_directory=str(root / 'data'),
                  model_directory=str(root / 'models'))
    module_launch('flexarm_compensator')
    return root


@pytest.fixture(scope='module')
def clients(graph, domain_id) -> Iterator[tuple[FlexarmClient, FlexarmClient]]:
    """Two clients of the graph (two operators' shells), ready."""
    made = []
    try:
        for name in ('operator_a', 'operator_b'):
            context = Context()
            rclpy.init(context=context, domain_id=domain_id)
            made.append((FlexarmClient(name, context=context), context))
            made[-1][0].wait_until_ready(timeout=liveness.limit(60.0))
        yield made[0][0], made[1][0]
    finally:
        for client, context in made:
            client.destroy_node()
            rclpy.try_shutdown(context=context)


def holding(client: FlexarmClient, kind: str = '', timeout: float = 60.0) -> ArmMotion:
    """The arm owner's ``arm/motion`` once a motion of ``kind`` holds the arm ('': once the
    arm is free)."""
    deadline = time.monotonic() + liveness.limit(timeout)
    while True:
        motion = client.messages_from(topics.ARM_MOTION, ArmMotion, 1, 10.0, qos=LATCHED,
                                      what='arm motions')[0]
        if motion.kind == kind or (not kind and not motion.motion_id):
            return motion
        if time.monotonic() > deadline:
            pytest.fail(f'no {kind or "free"} arm within {timeout} s: {motion}')
        time.sleep(0.05)


def fresh(name: str) -> str:
    return f'{name}-{uuid.uuid4().hex[:8]}'


def test_a_move_during_a_collection_is_refused_and_the_collection_stays_undisturbed(
        graph, clients):
    a, b = clients
    dataset = fresh('undisturbed')
    run = a.collect_async(30, region='A', dataset=dataset, timeout=300)
    motion = holding(b, 'collect')
    assert motion.holder == '/flexarm_learner' and 'operator_a' in motion.sender
    refused = b.move_to(*B4, mode='rigid', trial='intruder', timeout=60)
    assert refused.error_code == MoveToPose.Result.ARM_BUSY, refused.error_string
    for part in ('the arm is busy: collect "30 samples (sobol) in region A', '/operator_a',
                 '/flexarm_learner', motion.motion_id, 'nothing moved'):
        assert part in refused.error_string, refused.error_string
    assert refused.motion == '' and refused.iterations == 0
    deadline = time.monotonic() + liveness.limit(60.0)
    while run.feedback() is None and not run.done():       # a sample after the refusal
        assert time.monotonic() < deadline, 'no sample of the collection after the refusal'
        run.done(0.1)
    run.cancel()
    result = run.result()
    assert result.error_code == CollectSamples.Result.CANCELED
    assert result.collected >= 1 and result.skipped == 0
    samples = load_dataset(result.dataset_path).samples
    assert len(samples) == result.collected
    assert {s.motion for s in samples} == {motion.motion_id}    # each knows it was undisturbed
    holding(b, '')


def test_a_collection_during_a_move_is_refused_and_the_move_succeeds(graph, clients):
    a, b = clients
    run = a.move_async(*B4, mode='rigid', trial='long_way', timeout=120)
    motion = holding(b, 'move')
    assert 'MoveToPose long_way (rigid)' in motion.description
    dataset = fresh('refused')
    refused = b.collect(3, region='A', dataset=dataset, timeout=60)
    assert refused.error_code == CollectSamples.Result.ARM_BUSY, refused.error_string
    assert f'move "{motion.description}"' in refused.error_string
    assert '/flexarm_compensator' in refused.error_string
    assert refused.collected == 0 and not (graph / 'data' / f'{dataset}.jsonl').exists()
    moved = run.result()
    assert moved.error_code == MoveToPose.Result.SUCCESSFUL, moved.error_string
    assert moved.motion == motion.motion_id
    holding(b, '')


def test_a_calibration_during_a_collection_is_refused_and_stores_nothing(graph, clients,
                                                                         tmp_path):
    a, b = clients
    run = a.collect_async(30, region='A', dataset=fresh('calibration'), timeout=300)
    motion = holding(b, 'collect')
    path = tmp_path / 'tool_camera.json'
    with pytest.raises(ArmBusy, match=f'the arm is busy: collect .*{motion.motion_id}'):
        calibrate_tool(b, topics.TIP_POSE_TRUTH, path, timeout=60.0, say=lambda _: None)
    assert not path.exists()
    run.cancel()
    assert run.result().error_code == CollectSamples.Result.CANCELED
    holding(b, '')


def test_a_refresh_during_a_move_is_refused(graph, clients, write_dataset):
    a, b = clients
    write_dataset(graph / 'data' / 'good.jsonl')
    trained = a.train('rbf', dataset='good', timeout=120)
    assert trained.success, trained.message
    run = a.move_async(*A1, mode='rigid', trial='to_a1', timeout=120)
    motion = holding(b, 'move')
    refused = b.refresh(2, region='A', force=True, timeout=60)
    assert refused.error_code == RefreshModel.Result.ARM_BUSY, refused.error_string
    assert 'MoveToPose to_a1 (rigid)' in refused.error_string
    assert refused.collected == 0
    assert run.result().error_code == MoveToPose.Result.SUCCESSFUL
    assert holding(b, '').ended == f'move motion {motion.motion_id} released'


def test_cancel_ends_a_calibration_between_its_poses(graph, clients):
    a, b = clients
    with a.claimed_arm('calibrate', 'a calibration of the test') as motion:
        assert a.arm_held() == ''
        first = a.move_to(*A1, mode='rigid', motion=motion, trial='pose_1', timeout=60)
        assert first.error_code == MoveToPose.Result.SUCCESSFUL and first.motion == motion
        intruder = b.move_to(*B4, mode='rigid', timeout=60)
        assert intruder.error_code == MoveToPose.Result.ARM_BUSY
        assert 'calibrate "a calibration of the test"' in intruder.error_string
        ended = b.end_motion()                                  # flexarm cancel
        assert ended.startswith('ended calibrate') and motion in ended
        deadline = time.monotonic() + liveness.limit(10.0)
        while not a.arm_held() and time.monotonic() < deadline:
            a.spin_once(0.05)
        assert 'canceled by /operator_b' in a.arm_held()
        late = a.move_to(*B4, mode='rigid', motion=motion, trial='pose_2', timeout=60)
        assert late.error_code == MoveToPose.Result.ARM_BUSY
        assert f'motion {motion} does not hold the arm' in late.error_string
    assert b.end_motion() == ''                                 # the arm is free


def test_a_holder_that_dies_frees_the_arm(graph, clients, domain_id, tmp_path):
    _, b = clients
    script = ('import time, rclpy\n'
              'from flexarm_control.ros.client import FlexarmClient\n'
              f'rclpy.init(domain_id={domain_id})\n'
              "client = FlexarmClient('doomed_holder')\n"
              "claim = client.claimed_arm('calibrate', 'held until killed')\n"
              'claim.__enter__()\n'
              "print('held', flush=True)\n"
              'time.sleep(600)\n')
    out = tmp_path / 'holder.out'
    with open(out, 'wb') as sink:
        doomed = subprocess.Popen([sys.executable, '-c', script], stdout=sink,
                                  stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    try:
        assert holding(b, 'calibrate').holder == '/doomed_holder', out.read_text()
    finally:
        doomed.send_signal(signal.SIGKILL)
        doomed.wait(timeout=30)
    freed = holding(b, '', timeout=30.0)
    assert freed.ended.endswith('ended with its holder /doomed_holder')
