"""The bottom of the flexarm stack: the robot's shared facts and basics (pure: kinematics, the
paper's tables, regions, topics, config and paths, the measurement, the tool correction, this
machine's processes) and, in ``ros``, the rclpy helpers every node shares. Every other flexarm
package may import it; it imports none of them."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_core.atomic_file',
    'flexarm_core.calibration_record',
    'flexarm_core.dds_profile',
    'flexarm_core.dds_shm',
    'flexarm_core.demand',
    'flexarm_core.frames',
    'flexarm_core.goal_sender',
    'flexarm_core.graph_locks',
    'flexarm_core.health_report',
    'flexarm_core.joint_trajectory',
    'flexarm_core.kinematics',
    'flexarm_core.liveness',
    'flexarm_core.measurement',
    'flexarm_core.natural_frequency',
    'flexarm_core.paper',
    'flexarm_core.parameter_schema',
    'flexarm_core.params',
    'flexarm_core.parent_death',
    'flexarm_core.paths',
    'flexarm_core.processes',
    'flexarm_core.plane',
    'flexarm_core.regions',
    'flexarm_core.tool_correction',
    'flexarm_core.topics',
    'flexarm_core.transport',
    'flexarm_core.ros.diagnostics',
    'flexarm_core.ros.node_main',
    'flexarm_core.ros.node_params',
    'flexarm_core.ros.scene_msgs',
    'flexarm_core.ros.stamps',
    'flexarm_core.ros.taken',
    'flexarm_core.ros.trajectory_message',
)
