"""Moving an arm as ros2_control's controller contracts say: the pure move and measurement
policy and the arm's ownership rules, and in ``ros`` the arm owner node (one commander per arm),
claims on it and the arm interface the learner and compensator drive it through (shaped joint
trajectories over FollowJointTrajectory, joint states, tip measurements)."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_motion.arm_motion',
    'flexarm_motion.ros.arm_claim',
    'flexarm_motion.ros.arm_interface',
    'flexarm_motion.ros.joint_commands',
)
