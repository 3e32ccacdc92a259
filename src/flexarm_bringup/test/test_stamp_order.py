"""Stamps are checked in order per stream: per /tf child, per /diagnostics node, per topic."""
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped, TransformStamped
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray

from flexarm_bringup.stamp_order import backwards_steps, header_stamps
from flexarm_msgs.msg import TipPose
from tf2_msgs.msg import TFMessage


def _header(sec: int) -> Header:
    return Header(stamp=Time(sec=sec, nanosec=5))


def test_each_header_of_a_message_is_in_its_stream() -> None:
    tf = TFMessage(transforms=[TransformStamped(header=_header(2), child_frame_id='link1'),
                               TransformStamped(header=_header(3), child_frame_id='link2')])
    assert list(header_stamps('/tf', tf)) == [(('/tf', 'link1'), 2_000_000_005),
                                              (('/tf', 'link2'), 3_000_000_005)]
    markers = MarkerArray(markers=[Marker(header=_header(4)), Marker(header=_header(4))])
    assert list(header_stamps('/m', markers)) == [(('/m', ''), 4_000_000_005)] * 2
    report = DiagnosticArray(header=_header(1), status=[DiagnosticStatus(name='arm1/sim: clock')])
    assert list(header_stamps('/diagnostics', report)) == [(('/diagnostics', 'arm1/sim'),
                                                            1_000_000_005)]
    assert list(header_stamps('/p', PoseStamped(header=_header(0)))) == [(('/p', ''), 5)]
    tip = TipPose(header=_header(0), status='not settled')      # a status of its own kind
    assert list(header_stamps('/tip_pose', tip)) == [(('/tip_pose', ''), 5)]
    assert list(header_stamps('/clock_like', Time(sec=1))) == []


def test_a_stream_steps_back_only_against_itself() -> None:
    a, b = ('/diagnostics', 'sim'), ('/diagnostics', 'vision')
    stamps = [(a, 10), (b, 8), (a, 11), (b, 9), (a, 11), (b, 1_700_000_000), (b, 12), (a, 3)]
    assert backwards_steps(stamps) == {a: 1, b: 1}
    assert backwards_steps([]) == {}
