"""Messages the control nodes build from numpy values."""
from __future__ import annotations

import numpy as np

from flexarm_msgs.msg import PlanarPose


def planar(pose: np.ndarray) -> PlanarPose:
    return PlanarPose(x=float(pose[0]), y=float(pose[1]), phi=float(pose[2]))
