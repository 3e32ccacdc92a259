"""Node-level: a camera that cannot measure (its focal length 8 % off what its camera_info says,
beyond what the vision node's fit takes for a calibration a little off). A collection
fails after a few poses with the vision node's reason instead of skipping through its whole
campaign, and a goal that needs a measurement says the same reason. Every other error source
is off: the camera alone makes it blind.
"""
import math

import pytest

from flexarm_control.collection import BLIND_POSES
from flexarm_msgs.action import CollectSamples, MoveToPose

pytestmark = [pytest.mark.node, pytest.mark.duration(25)]
SOURCES = ('repeatability', 'hysteresis', 'thermal', 'payload')
BLIND = {'error_sources': {'enabled': True, **{s: {'enabled': False} for s in SOURCES},
                           'camera': {'enabled': True, 'focal_length': 0.08}}}
QUICK = {'motion': {'measurement_timeout': 5.0}}     # [s, sim time] per measurement
TARGET = (1.30, -0.20, math.radians(-61))            # Table 10, B6
SAID = 'the vision node found no valid pose in '


def test_a_blind_camera_ends_a_collection_within_a_few_poses_and_says_why(
        launch, ready_client, tmp_path):
    launch('flexarm_sim', real_time_factor=10.0, **BLIND)
    launch('flexarm_vision', tool_calibration_file=str(tmp_path / 'none.json'))
    launch('flexarm_learner', data_directory=str(tmp_path / 'data'),
           model_directory=str(tmp_path / 'models'), measurement_retries=0, **QUICK)
    launch('flexarm_compensator', **QUICK)
    client = ready_client()

    collected = client.collect(20, region='B', dataset='blind', timeout=120)
    assert collected.error_code == CollectSamples.Result.FAILED, collected.error_string
    assert (collected.collected, collected.skipped) == (0, BLIND_POSES)
    assert 'the camera cannot measure: ' + SAID in collected.error_string, \
        collected.error_string

    moved = client.move_to(*TARGET, mode='rigid', position_tolerance=1e-3, timeout=60)
    assert moved.error_code == MoveToPose.Result.MEASUREMENT_FAILED, moved.error_string
    assert 'to check the tolerance: ' + SAID in moved.error_string, moved.error_string
