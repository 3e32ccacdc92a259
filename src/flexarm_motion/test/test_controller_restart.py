"""A restarted controller is told from the one a command went to by its new gid under its old
name (:mod:`flexarm_motion.controller_restart`)."""
from flexarm_motion.controller_restart import restarted

OLD, NEW, OTHER = b'\x01' * 16, b'\x02' * 16, b'\x03' * 16


def test_the_same_node_under_a_new_gid_is_a_restart():
    assert restarted([(OLD, '/flexarm_bridge')], [(NEW, '/flexarm_bridge')]) == [
        '/flexarm_bridge']
    assert restarted([(OLD, '/flexarm_bridge')], [(OLD, '/flexarm_bridge'),
                                                  (NEW, '/flexarm_bridge')]) == [
        '/flexarm_bridge']    # the dead one's endpoint lingers until its lease ends


def test_the_same_publisher_another_node_or_an_unnamed_one_is_none():
    assert restarted([(OLD, '/flexarm_bridge')], [(OLD, '/flexarm_bridge')]) == []
    assert restarted([(OLD, '/flexarm_bridge')], [(OLD, '/flexarm_bridge'),
                                                  (OTHER, '/joint_replay')]) == []
    assert restarted([(OLD, '/flexarm_bridge')], [(NEW, '?')]) == []
    assert restarted([], [(NEW, '/flexarm_bridge')]) == []     # none at the command
