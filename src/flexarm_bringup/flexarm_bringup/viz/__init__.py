"""What makes the graph visible: the scene node (working regions, learning samples, the learned
deflection field as markers) and the Foxglove node with its web front."""
