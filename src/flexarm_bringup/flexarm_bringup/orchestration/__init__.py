"""Starting, supervising and finding graphs: the launcher (one process per node of
config/graph.yaml), the supervisor behind ``flexarm up``, ROS domains and their reservations,
the DDS transports, and the status of a running graph."""
