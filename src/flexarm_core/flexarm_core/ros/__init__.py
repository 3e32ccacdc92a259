"""The rclpy helpers every node shares: how a node runs and ends, its parameters, diagnostics,
stamps, taken subscriptions, and the message forms of trajectories and scene poses. The rest
of flexarm_core is pure and imports no ROS package (tests/test_layering.py)."""
