"""How a test listens to ``/tf_static``: as tf2_ros's static listener does (transient local,
depth 100). The graph has two latched publishers of it, the state publisher and the vision
node, and each sends its transforms when a subscriber joins; a depth of 1 kept only the later
when both came before the executor took the first."""
from rclpy.qos import QoSDurabilityPolicy, QoSProfile

STATIC_TF_QOS = QoSProfile(depth=100, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
