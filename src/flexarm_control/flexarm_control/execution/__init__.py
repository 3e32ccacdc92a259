"""Executing goals and campaigns: compensation and planning, goal bounds and the check after a
move, the collection loop, the tool calibration against a reference (pure: no rclpy)."""
