"""Executing goals and campaigns: compensation and planning, the goal and collection loops over
one arm-motion helper, goal bounds, the tool calibration against a reference (pure: no rclpy)."""
