"""The ROS shell of motion: the arm owner node, claims on an arm, the joint commands and the arm
interface; the only modules of flexarm_motion that import rclpy."""
