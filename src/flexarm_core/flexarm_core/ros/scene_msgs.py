"""Planar poses as ROS 3-D messages (the node side of :mod:`flexarm_core.plane`)."""
from __future__ import annotations

from collections.abc import Sequence

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion
from std_msgs.msg import Header

from flexarm_core import plane

BASE_FRAME = 'base_link'


def pose_stamped(pose: Sequence[float], stamp: Time) -> PoseStamped:
    """A planar pose (x, y_up, phi) [m, m, rad] as a base_link PoseStamped."""
    x, y, z = plane.position(pose)
    qx, qy, qz, qw = plane.orientation(float(pose[2]))
    return PoseStamped(header=Header(stamp=stamp, frame_id=BASE_FRAME),
                       pose=Pose(position=Point(x=x, y=y, z=z),
                                 orientation=Quaternion(x=qx, y=qy, z=qz, w=qw)))
