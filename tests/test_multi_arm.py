"""Node-level: two arms in one ROS domain, each a whole graph under its own namespace.

arm1 and arm2 collect at once (8 samples each, regions A and B), train, and reach a PREDICTIVE
goal at once (one client per arm, each in a thread). Each arm must learn from and move with its
own data only: its compensator runs its own model (from its own model folder), and no topic
under ``/armK/`` has a publisher outside ``/armK`` (checked over every discovered topic while
the arms work), nor do samples or goal outcomes of one arm appear on the other's topics; the
domain has one ``/clock``, arm1's. The ideal world, as in test_compensator_node.py: the
behaviour must not hang on noise.
"""
from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.context import Context
from rclpy.qos import QoSDurabilityPolicy, QoSProfile

from flexarm_bringup.supervisor import Graph
from flexarm_control.ros.client import FlexarmClient
from flexarm_core import topics
from flexarm_deflection.dataset import load_dataset
from flexarm_msgs.action import CollectSamples, MoveToPose
from flexarm_msgs.msg import DeflectionSample, GoalOutcome, ModelInfo

pytestmark = [pytest.mark.node, pytest.mark.timeout(300), pytest.mark.duration(95)]
IDEAL = {'error_sources': {'enabled': False}}
ARMS = {'arm1': ('A', 1), 'arm2': ('B', 2)}    # namespace: region and seed of its samples
SAMPLES = 8
# arm1 publishes /clock and arm2 follows it, said outright: the supervisor's own choice looks for a
# /clock publisher for a bounded time (CLOCK_WAIT), which the first arm would wait out, and
# under heavy load might find none yet.
FOLLOWER = {'clock_source': 'follow'}
OWNER = {'clock_source': 'own'}
UNKNOWN = '_NODE_NAMESPACE_UNKNOWN_'            # discovery's placeholder until names arrive


def foreign_publishers(node: Any, namespaces: tuple[str, ...]) -> set[tuple[str, str]]:
    """(topic, publisher's node) of every discovered topic under ``/<ns>/`` published by a
    node outside ``/<ns>``; publishers whose node is not known yet are left for a later look."""
    found = set()
    for topic, _ in node.get_topic_names_and_types():
        for ns in namespaces:
            if topic.startswith(f'/{ns}/'):
                found |= {(topic, f'{p.node_namespace}/{p.node_name}')
                          for p in node.get_publishers_info_by_topic(topic)
                          if p.node_namespace not in (f'/{ns}', UNKNOWN)}
    return found


def published_topics(node: Any, ns: str) -> set[str]:
    """Topics under ``/<ns>/`` with at least one publisher in ``/<ns>``."""
    return {topic for topic, _ in node.get_topic_names_and_types()
            if topic.startswith(f'/{ns}/') and any(
                p.node_namespace == f'/{ns}' for p in node.get_publishers_info_by_topic(topic))}


def joints_of(samples: list[DeflectionSample]) -> set[tuple[float, ...]]:
    return {tuple(float(v) for v in m.joint_positions) for m in samples}


def in_threads(job: Callable[[str], Any], timeout: float) -> dict[str, Any]:
    """``job(ns)`` for every arm at once; each one's result (or exception, raised here)."""
    results: dict[str, Any] = {}

    def run(ns: str) -> None:
        try:
            results[ns] = job(ns)
        except Exception as exc:     # re-raised in the test's thread
            results[ns] = exc

    threads = [threading.Thread(target=run, args=(ns,)) for ns in ARMS]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout)
    late = sorted(set(ARMS) - set(results))
    assert not late, f'no result within {timeout} s from {late}'
    for value in results.values():
        if isinstance(value, Exception):
            raise value
    return results


@pytest.fixture
def arms(domain_id, tmp_path):
    """Both graphs (arm1 first: its simulator publishes /clock) and a client per arm."""
    learner = {'data_directory': str(tmp_path / 'data'),
               'model_directory': str(tmp_path / 'models')}
    graphs: list[Graph] = []
    clients: dict[str, FlexarmClient] = {}
    contexts: list[Context] = []
    try:
        for ns in ARMS:
            sim = {'real_time_factor': 10.0, **IDEAL, **(FOLLOWER if graphs else OWNER)}
            graphs.append(Graph(domain_id, tmp_path / 'run' / ns, namespace=ns, parameters={
                'flexarm_sim': sim, 'flexarm_learner': learner}))
            graphs[-1].start()
            graphs[-1].wait_ready(90.0)
        for ns in ARMS:
            contexts.append(Context())
            rclpy.init(context=contexts[-1], domain_id=domain_id)
            clients[ns] = FlexarmClient('test_client', context=contexts[-1], namespace=ns)
            clients[ns].wait_until_ready(timeout=30.0)
        yield clients, tmp_path
    finally:
        for client, context in zip(clients.values(), contexts):
            client.destroy_node()
            rclpy.try_shutdown(context=context)
        for graph in reversed(graphs):      # the /clock owner last
            graph.stop(timeout=10.0)


def test_two_arms_learn_and_move_each_with_its_own_data_only(arms, ros_node, wait_for):
    clients, tmp = arms
    latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
    heard: dict[str, dict[str, list]] = {ns: {'samples': [], 'models': [], 'active': [],
                                              'outcomes': []} for ns in ARMS}
    matched = []
    for ns, lists in heard.items():
        for kind, message, topic, qos in (
                ('samples', DeflectionSample, topics.SAMPLES, 100),
                ('models', ModelInfo, topics.MODEL, latched),
                ('active', ModelInfo, topics.ACTIVE_MODEL, latched),
                ('outcomes', GoalOutcome, topics.OUTCOMES, 10)):
            matched.append(ros_node.create_subscription(
                message, topics.absolute(topic, ns), lists[kind].append, qos))
    # A sample published before its subscription matched would not be heard.
    wait_for(lambda: all(s.get_publisher_count() for s in matched), 30.0,
             "the arms' publishers matched")
    statuses: set[str] = set()
    ros_node.create_subscription(DiagnosticArray, '/diagnostics',
                                 lambda m: statuses.update(s.name for s in m.status), 10)
    foreign: set[tuple[str, str]] = set()
    watching = threading.Event()

    def watch() -> None:                 # every discovered topic, while the arms work
        while not watching.wait(0.5):
            foreign.update(foreign_publishers(ros_node, tuple(ARMS)))
    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    try:
        collected = in_threads(lambda ns: clients[ns].collect(
            SAMPLES, region=ARMS[ns][0], seed=ARMS[ns][1], dataset='d', timeout=150), 160)
        for ns, result in collected.items():
            assert result.error_code == CollectSamples.Result.SUCCESSFUL, result.error_string
            assert result.collected >= SAMPLES - 1
            assert Path(result.dataset_path).parent == tmp / 'data' / ns

        trained = in_threads(lambda ns: clients[ns].train('', dataset='d', timeout=120), 130)
        for ns, response in trained.items():
            assert response.success, response.message
            assert Path(response.model_path).parent == tmp / 'models' / ns
            clients[ns].wait_for_model(response.model_version, timeout=30)

        datasets = {ns: load_dataset(r.dataset_path) for ns, r in collected.items()}
        targets = {ns: datasets[ns].samples[0].measured_pose for ns in ARMS}  # learned there
        moved = in_threads(lambda ns: clients[ns].move_to(
            *targets[ns], mode='predictive', trial=f'{ns}-goal', timeout=120), 130)
        for ns, result in moved.items():
            assert result.error_code == MoveToPose.Result.SUCCESSFUL, result.error_string
            assert result.model_version == trained[ns].model_version
        wait_for(lambda: all(
            heard[ns]['outcomes'] and heard[ns]['active']
            and heard[ns]['active'][-1].path == trained[ns].model_path
            and len(heard[ns]['samples']) >= len(datasets[ns].samples)
            and any(name.startswith(f'{ns}/flexarm_sim: ') for name in statuses)
            for ns in ARMS), 20.0, "each arm's outcome, samples, model and status heard")
        foreign.update(foreign_publishers(ros_node, tuple(ARMS)))
        checked = {ns: published_topics(ros_node, ns) for ns in ARMS}
        clocks = [(p.node_namespace, p.node_name)
                  for p in ros_node.get_publishers_info_by_topic(topics.CLOCK)]
    finally:
        watching.set()
        watcher.join(timeout=5.0)

    for ns in ARMS:         # the look above was not empty: each arm's own topics were there
        assert {topics.absolute(t, ns) for t in (topics.JOINT_STATES, topics.TIP_POSE,
                                                 topics.SAMPLES, topics.OUTCOMES)} <= checked[ns]
    assert foreign == set()
    assert clocks == [('/arm1', 'flexarm_sim')]         # one clock in the domain: arm1's
    assert {datasets['arm1'].hash, trained['arm1'].model_path} \
        .isdisjoint({datasets['arm2'].hash, trained['arm2'].model_path})
    for ns in ARMS:
        assert heard[ns]['models'][-1].path == trained[ns].model_path
        assert heard[ns]['active'][-1].path == trained[ns].model_path
        assert [o.trial for o in heard[ns]['outcomes']] == [f'{ns}-goal']
        assert heard[ns]['outcomes'][0].model_version == trained[ns].model_version
        assert joints_of(heard[ns]['samples']) == {s.joints for s in datasets[ns].samples}
        assert any(name.startswith(f'{ns}/flexarm_sim: ') for name in statuses), statuses
    assert not joints_of(heard['arm1']['samples']) & joints_of(heard['arm2']['samples'])
