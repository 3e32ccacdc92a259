"""The real-robot boundary: the controller protocol (PROTOCOL.md), its authentication, and the
bridge node between ROS and a robot controller."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_bridge.controller_protocol',
    'flexarm_bridge.link_auth',
    'flexarm_bridge.tcp_link',
)
