"""What makes the graph visible: the scene node (working regions, learning samples, the learned
deflection field as markers) and the Foxglove node with its web front."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_viz.foxglove_node',
)
