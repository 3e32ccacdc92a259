"""Node-level: what `flexarm move` says, and how it exits, when the compensator is busy, when
the move is interrupted (Ctrl-C, SIGTERM: the goal is cancelled and the CLI says where the arm
stopped) and when the server refuses the goal. Interrupted and busy commands run as their own
processes, as an operator runs them; refusals call ``main`` in this process.
"""
from __future__ import annotations

import math
import re
import signal
import time

import numpy as np
import pytest
from sensor_msgs.msg import JointState

from flexarm_cli import main
from flexarm_core import liveness, topics
from flexarm_core.kinematics import ArmGeometry, forward
from flexarm_core.params import load_config
from flexarm_recording.results.outcome_text import Exit
from flexarm_test_support.cli_process import Cli, no_cli_left  # noqa: F401  (autouse fixture)
from flexarm_test_support.joint_watch import JointWatch
from flexarm_test_support.run_record import record_supervisor

pytestmark = [pytest.mark.node, pytest.mark.duration(95)]
B4 = ('1000', '-500', '-100')      # [mm, mm, deg] Table 10: a long move from the start pose
A1 = ('1450', '-150', '-45')
STOPPED = re.compile(r'cancelled; arm stopped at x=(\S+) mm, y=(\S+) mm, phi=(\S+) deg')


class Arm:
    """The arm's rigid tip pose [m, m, rad] from /joint_states, as a test client sees it."""

    STILL = 0.3   # [s, sim time] without joint motion: the arm is at rest

    def __init__(self, client) -> None:
        self._client, self._watch = client, JointWatch()
        self._geometry = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])
        client.create_subscription(JointState, topics.JOINT_STATES, self._watch.on_joints, 10)

    def _spin(self) -> None:
        self._client.spin_once(0.2)

    def at_rest(self, timeout: float = 30.0) -> np.ndarray:
        """The pose once the joints have not moved for ``STILL`` s of the simulator's time."""
        deadline = time.monotonic() + liveness.limit(timeout)
        while time.monotonic() < deadline:
            self._spin()
            if self._watch.q is not None and self._watch.still_for >= self.STILL:
                return forward(self._geometry, self._watch.q)
        pytest.fail(f'the joints did not come to rest within {timeout} s')

    def away_from(self, pose: np.ndarray, distance: float, timeout: float = 30.0) -> None:
        """Return once the tip is ``distance`` [m] away from ``pose``."""
        deadline = time.monotonic() + liveness.limit(timeout)
        while time.monotonic() < deadline:
            self._spin()
            if self._watch.q is not None and np.linalg.norm(
                    forward(self._geometry, self._watch.q)[:2] - pose[:2]) > distance:
                return
        pytest.fail(f'the tip did not move {distance * 1e3:.0f} mm within {timeout} s')


@pytest.fixture
def arm(launch, ready_client) -> Arm:
    """Simulator at 0.15 x real time (a long move lasts ~20 s, time for a second `flexarm`
    process to start) and the compensator."""
    launch('flexarm_sim', real_time_factor=0.15)
    launch('flexarm_compensator')
    return Arm(ready_client(learner=False))


def stopped_pose(err: str) -> np.ndarray:
    """The pose [m, m, rad] an interrupted `flexarm move` said the arm stopped at."""
    found = STOPPED.search(err)
    assert found, err
    x, y, phi = (float(v) for v in found.groups())
    return np.array([x / 1e3, y / 1e3, math.radians(phi)])


def interrupt(move: Cli, signum: int, arm: Arm) -> np.ndarray:
    """Send ``signum`` to a moving `flexarm move`; where it said the arm stopped, checked
    against where the arm is at rest."""
    move.process.send_signal(signum)
    code, err = move.finish(15.0)
    assert code == Exit.INTERRUPTED and 'Traceback' not in err, err
    said, rest = stopped_pose(err), arm.at_rest()
    assert np.max(np.abs(said[:2] - rest[:2])) < 0.5e-3, (said, rest)   # held where it said
    assert abs(said[2] - rest[2]) < math.radians(0.05), (said, rest)
    return said


def test_busy_and_interrupted_moves_say_so_and_where_the_arm_stopped(arm, domain_id):
    start = arm.at_rest()
    first = Cli('move', *B4, '--mode', 'rigid', domain_id=domain_id)
    first.wait_line('] moving', 60.0)
    code, err = Cli('move', *A1, '--mode', 'rigid', domain_id=domain_id).finish(60.0)
    assert code == Exit.BUSY, err
    assert 'flexarm move: refused (ARM_BUSY; nothing moved): the arm is busy: ' in err
    assert 'runs goal (no trial name) (rigid)' in err and 'flexarm cancel' in err

    arm.away_from(start, 0.01)
    said = interrupt(first, signal.SIGINT, arm)
    target = np.array([float(B4[0]) / 1e3, float(B4[1]) / 1e3])
    assert np.linalg.norm(said[:2] - target) > 0.02                      # stopped mid-way

    second = Cli('move', *A1, '--mode', 'rigid', domain_id=domain_id)
    second.wait_line('] moving', 60.0)
    arm.away_from(said, 0.005)
    interrupt(second, signal.SIGTERM, arm)


def test_refusals_name_their_code_in_mm_with_a_hint(launch, domain_id, capsys):
    launch('flexarm_sim', real_time_factor=10.0)
    launch('flexarm_compensator')
    graph = ['--domain-id', str(domain_id)]
    assert main(['move', '2500', '0', '0', '--mode', 'rigid', *graph]) == Exit.FAILED
    err = capsys.readouterr().err
    assert 'flexarm move: refused (UNREACHABLE; nothing moved): pose (x=2500 mm, y=0 mm' in err
    assert 'what to do: choose a target the arm can reach' in err
    assert not re.search(r'\d m\b', err)                                 # no metres left

    assert main(['move', *A1, *graph]) == Exit.FAILED                    # predictive, no model
    err = capsys.readouterr().err
    assert 'refused (NO_MODEL; nothing moved)' in err and 'flexarm train' in err

    assert main(['move', *A1, '--mode', 'rigid', *graph]) == Exit.OK     # no camera here
    captured = capsys.readouterr()
    assert 'moved (uncompensated) in 1 move(s), not measured' in captured.out, captured
    assert '[1] moving' in captured.err and '[1] moving' not in captured.out


def test_training_says_why_it_failed_and_what_it_made(launch, domain_id, tmp_path,
                                                      write_dataset, capsys):
    launch('flexarm_learner', data_directory=str(tmp_path), model_directory=str(tmp_path))
    launch('flexarm_compensator')
    write_dataset(tmp_path / 'small.jsonl', count=12)
    graph = ['--domain-id', str(domain_id)]
    assert main(['train', 'rbf', '--dataset', 'missing', *graph]) == Exit.FAILED
    err = capsys.readouterr().err
    assert f'flexarm train: training failed: no dataset at {tmp_path}/missing.jsonl' in err
    assert 'what to do: ' in err and 'Traceback' not in err

    assert main(['train', 'rbf', '--dataset', 'small', *graph]) == Exit.OK
    out = capsys.readouterr().out
    assert re.search(r'12 samples: max \|error\| x \S+ mm, y \S+ mm, phi \S+ deg', out), out


def test_status_model_list_use_and_dry_run(launch, domain_id, tmp_path, write_dataset,
                                           ready_client, capsys, request):
    import json

    data, models = tmp_path / 'data', tmp_path / 'models'
    write_dataset(data / 'good.jsonl', count=20)
    nodes = [launch('flexarm_sim', real_time_factor=10.0),
             launch('flexarm_learner', data_directory=str(data), model_directory=str(models)),
             launch('flexarm_compensator')]
    # the run record `flexarm up` would write: status knows the nodes at once, instead of
    # waiting on a fresh participant's discovery (once over 12 s under a full load)
    record = record_supervisor(domain_id, '', nodes)
    request.addfinalizer(record.unlink)
    client = ready_client()
    domain = ['--domain-id', str(domain_id)]
    for _ in range(2):
        assert client.train('rbf', dataset='good', timeout=60).success
    client.wait_for_model('2', timeout=20)
    capsys.readouterr()

    assert main(['status', '--json', *domain]) == Exit.OK
    out = capsys.readouterr().out
    status = json.loads(out.splitlines()[-1])
    assert status['active_model']['version'] == '2' and status['controller'] == 'sim'
    assert status['active_model']['dataset'] == 'good', status
    assert status['payload_kg']['learner'] == 0, status
    assert 'model driving the arm (compensator): v2 rbf, dataset good, 20 samples' in out
    assert 'model health: no measured goal yet' in out

    assert main(['payload', '2.5', *domain]) == Exit.OK
    assert 'payload: 2.5 kg (declared now)' in capsys.readouterr().out
    assert main(['refresh', *domain]) == Exit.FAILED        # nothing stale: nothing moves
    assert 'no stale region' in capsys.readouterr().err

    assert main(['model', 'list', '--models', str(models)]) == Exit.OK
    listed = capsys.readouterr().out
    assert re.search(r'^  good-rbf-v1\.model: v1 rbf', listed, re.M)
    assert re.search(r'^\* good-rbf-v2\.model: v2 rbf', listed, re.M)

    assert main(['model', 'use', '1', *domain]) == Exit.OK
    assert 'model driving the arm now: v1 rbf' in capsys.readouterr().out
    assert client.active_model.version == '1' or client.wait_for_model('1', 10)
    assert main(['model', 'use', '7', *domain]) == Exit.FAILED
    assert 'no model version 7' in capsys.readouterr().err

    assert main(['move', *A1, '--dry-run', '--allow-extrapolation', '--json', *domain]) == 0
    out = capsys.readouterr().out
    assert 'plan (model v1; nothing moved): command x=' in out
    plan = json.loads(out.splitlines()[-1])
    assert plan['model_version'] == '1' and plan['iterations'] == 0 and plan['dry_run']
