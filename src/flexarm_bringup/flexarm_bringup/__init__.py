"""The graph's configuration and what starts it: the launcher (one process per node of
config/graph.yaml), the supervisor behind ``flexarm up``, ROS domains and their reservations,
and the status of a running graph."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_bringup.domains',
    'flexarm_bringup.graph_status',
    'flexarm_bringup.graph_watch',
    'flexarm_bringup.launcher',
    'flexarm_bringup.running_graphs',
    'flexarm_bringup.status_text',
    'flexarm_bringup.supervisor',
    'flexarm_bringup.up_domain',
)
