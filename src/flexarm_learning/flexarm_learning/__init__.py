"""The learning core: how far a serial arm misses what its description says, learned from
measurements, with a calibrated bound; pure (no rclpy), usable offline (``flexarm accuracy``)."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_learning.accuracy_study',
    'flexarm_learning.ard_gp',
    'flexarm_learning.arm_error',
    'flexarm_learning.choices',
    'flexarm_learning.elastostatic',
    'flexarm_learning.measurements',
    'flexarm_learning.online_radius',
    'flexarm_learning.urdf_arm',
)
