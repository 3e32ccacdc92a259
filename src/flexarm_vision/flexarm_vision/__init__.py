"""The tip camera's view of the coded hole plate: camera model and calibration, hole detection,
the pose fit, settledness, and the vision node that publishes the tip pose."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_vision.camera_calibration',
    'flexarm_vision.camera_info',
    'flexarm_vision.camera_info_file',
    'flexarm_vision.camera_model',
    'flexarm_vision.image_encoding',
    'flexarm_vision.plate',
    'flexarm_vision.pose_estimator',
)
