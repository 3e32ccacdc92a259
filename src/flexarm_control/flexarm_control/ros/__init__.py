"""The ROS shell: the learner and compensator nodes and the scriptable client; the only modules
of flexarm_control that import rclpy."""
