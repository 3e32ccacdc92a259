"""The robot model: the URDF written from config/arm.yaml, its chain of frames, the scene's
marker geometry and the robot-state publisher node."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_description.chain',
    'flexarm_description.scene',
    'flexarm_description.tf_message',
    'flexarm_description.urdf_model',
)
