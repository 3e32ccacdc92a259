"""Stamps are checked in order per stream: per /tf child, per /diagnostics node, per topic;
and against the graph's time when each message was sent."""
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped, TransformStamped
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray

from flexarm_msgs.msg import TipPose
from flexarm_test_support.stamp_order import backwards_steps, beyond_sent, header_stamps
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


def _clock(sec: int) -> Clock:
    return Clock(clock=Time(sec=sec))


def _pose(sec: int, nanosec: int = 0) -> PoseStamped:
    return PoseStamped(header=Header(stamp=Time(sec=sec, nanosec=nanosec)))


def test_a_stamp_is_bounded_by_the_first_clock_published_after_it() -> None:
    """A simulator's burst leaves ahead of the newest /clock, and a recorder that lost /clock
    messages or stopped before the last ones still bounds nothing wrongly."""
    s = 1_000_000_000
    recording = [
        ('/clock', _clock(10), 100 * s),
        ('/joint_states', _pose(10, 100), 100 * s + 1),     # burst after /clock 10: ahead
        ('/joint_states', _pose(10, 190), 100 * s + 2),
        ('/tf', _pose(10, 190), 101 * s),                   # /clock 11 and 12 not recorded
        ('/clock', _clock(13), 103 * s),
        ('/tf', _pose(14), 104 * s),                        # after the last recorded /clock
        ('/diagnostics', DiagnosticArray(header=Header(stamp=Time(sec=13)),
                                         status=[DiagnosticStatus(name='sim: clock')]), 104 * s),
    ]
    assert beyond_sent(recording, final_ns=15 * s) == {}
    assert beyond_sent(recording, final_ns=13 * s) == {('/tf', ''): s}
    assert beyond_sent([], final_ns=0) == {}


def test_wall_time_and_future_stamps_are_beyond() -> None:
    s = 1_000_000_000
    recording = [('/clock', _clock(10), 100 * s), ('/p', _pose(12), 102 * s),
                 ('/clock', _clock(11), 101 * s),           # in publish order, not bag order
                 ('/p', _pose(11, 5), 100 * s + 5), ('/q', _pose(1_700_000_000), 100 * s),
                 ('/clock', _clock(13), 103 * s)]
    assert beyond_sent(recording, final_ns=13 * s) == {
        ('/p', ''): 5, ('/q', ''): 1_700_000_000 * s - 10 * s}
