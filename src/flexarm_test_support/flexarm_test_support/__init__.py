"""The test tooling of the flexarm graph, one package that the node-level tests (tests/) and the
benchmarks import: stand-ins for a ros2_control arm (``ros2_control_standin``) and for raw goal
senders (``abandoned_goal``), the controller-link proxy and its attacks, a peer on another host
in a network namespace (``remote_peer``), the learn-and-reach ending of node tests, joint-state
and run-record watchers, how a test listens to /tf_static (``tf_listening``), and the checks of
a recorded bag's stamps (``stamp_order``), what source files import (``source_imports``), and a
script's smoke run (``script_smoke``). A
package's own unit tests use only what lies at or below it (flexarm_control's fake arm lives in
its test folder); this package sits above every other."""

# What other packages may import (tests/test_layering.py holds every import to it).
PUBLIC = (
    'flexarm_test_support.abandoned_goal',
    'flexarm_test_support.cli_process',
    'flexarm_test_support.joint_watch',
    'flexarm_test_support.learned_goal',
    'flexarm_test_support.link_attacks',
    'flexarm_test_support.link_proxy',
    'flexarm_test_support.remote_peer',
    'flexarm_test_support.ros2_control_standin',
    'flexarm_test_support.run_record',
    'flexarm_test_support.script_smoke',
    'flexarm_test_support.source_imports',
    'flexarm_test_support.stamp_order',
    'flexarm_test_support.tf_listening',
)
