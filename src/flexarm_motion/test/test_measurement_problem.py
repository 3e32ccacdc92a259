"""Why a measurement failed, in the vision node's own words (no node started)."""
from flexarm_motion.ros.arm_interface import measurement_problem
from flexarm_msgs.msg import TipPose


def frame(valid: bool, settled: bool, status: str = '') -> TipPose:
    return TipPose(valid=valid, settled=settled, status=status)


def test_the_vision_nodes_reason_reaches_the_caller() -> None:
    assert 'no tip pose came from the vision node' in measurement_problem([], 3)
    blind = [frame(False, False, 'plate code not found'),
             frame(False, False, 'fit residual 0.155 mm RMS too large')]
    assert measurement_problem(blind, 3) == (
        'the vision node found no valid pose in 2 frame(s): fit residual 0.155 mm RMS too large'
        " (see the vision node's diagnostics (flexarm status); a camera off its camera_info: "
        'flexarm calibrate --camera)')
    ringing = [frame(True, False, 'tip moving 0.8 mm/s')]
    assert measurement_problem(ringing, 3) == 'the tip did not settle: tip moving 0.8 mm/s'
    few = [frame(True, True), frame(False, False, 'hole off its fitted position by 0.3 mm')]
    assert measurement_problem(few, 3) == ('only 1 of the 3 valid settled frames needed (the '
                                           'others: hole off its fitted position by 0.3 mm)')
