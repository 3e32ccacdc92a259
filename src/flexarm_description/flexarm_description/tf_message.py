"""The frames of the robot description as tf2 messages: what the state publisher puts on
``/tf`` and ``/tf_static``, and the vision node its calibrated camera mount."""
from __future__ import annotations

from geometry_msgs.msg import TransformStamped
from std_msgs.msg import Header

from flexarm_description.chain import Transform


def transform_msg(t: Transform, header: Header) -> TransformStamped:
    """``t`` stamped as ``header`` is (its frame ids are ``t``'s own)."""
    msg = TransformStamped(header=Header(stamp=header.stamp, frame_id=t.parent),
                           child_frame_id=t.child)
    msg.transform.translation.x, msg.transform.translation.y, msg.transform.translation.z = (
        t.translation)
    r = msg.transform.rotation
    r.x, r.y, r.z, r.w = t.rotation
    return msg
