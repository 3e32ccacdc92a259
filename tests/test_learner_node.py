"""Node-level: collect -> train -> model announced and hot-reloaded by the compensator.

The module's tests share one graph (simulator, camera, learner, compensator; started once,
stopped when the module ends), its data and model directories and a client. They stay apart
by what they name and compare: each collects into and trains on datasets of its own (fresh
names), listens only to what is published while it runs, and a test that checks model
versions compares them with the versions on disk when it starts, not with a number that
assumes no other test trained before it.
"""
import threading
import time
import uuid

import pytest
import rclpy
from rclpy.context import Context
from rclpy.qos import QoSDurabilityPolicy, QoSProfile

from flexarm_control.ros.client import FlexarmClient
from flexarm_core import topics
from flexarm_deflection.dataset import load_dataset
from flexarm_deflection.model_store import read_current, versions_on_disk
from flexarm_deflection.models import load_model
from flexarm_msgs.action import CollectSamples
from flexarm_msgs.msg import DeflectionSample, ModelInfo

pytestmark = [pytest.mark.node, pytest.mark.duration(80)]
DAMAGED_RECORD = '{"version": "2"}'    # current.json without kind and path: no record


def fresh(name: str) -> str:
    """A dataset name no other test (or earlier run of this one) of the module uses: the
    data directory is shared, and a collection appends to an existing dataset."""
    return f'{name}-{uuid.uuid4().hex[:8]}'


@pytest.fixture(scope='module')
def graph(module_launch, tmp_path_factory):
    """The module's graph; its folder holds ``data`` (datasets ``no_version``, a header
    without a version, and ``good``: :func:`good`) and ``models``, whose ``current.json`` is
    damaged beside a model file v3 when the learner starts."""
    root = tmp_path_factory.mktemp('learner')
    data, models = root / 'data', root / 'models'
    data.mkdir()
    models.mkdir()
    (models / 'current.json').write_text(DAMAGED_RECORD)
    (models / 'good-rbf-v3.model').write_bytes(b'an older model')
    (data / 'no_version.jsonl').write_text('{"format": "flexarm-deflection-dataset"}\n')
    module_launch('flexarm_sim', real_time_factor=10.0)
    module_launch('flexarm_vision')
    module_launch('flexarm_learner', data_directory=str(data), model_directory=str(models))
    module_launch('flexarm_compensator')
    return root


@pytest.fixture
def good(graph, write_dataset):
    """The dataset ``good`` (written once: read-only for the tests)."""
    path = graph / 'data' / 'good.jsonl'
    if not path.exists():
        write_dataset(path)
    return path


def open_client(domain_id: int, name: str) -> tuple[FlexarmClient, Context]:
    """A FlexarmClient ``name`` in a context of its own on the module's domain."""
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    try:
        return FlexarmClient(name, context=context), context
    except BaseException:
        rclpy.try_shutdown(context=context)
        raise


@pytest.fixture(scope='module')
def client(graph, domain_id):
    """The tests' client, ready: one for the module (a new client waits seconds for
    discovery); each goal or call of a test has ended when the test ends."""
    made, context = open_client(domain_id, 'test_client')
    try:
        made.wait_until_ready(timeout=30.0)
        yield made
    finally:
        made.destroy_node()
        rclpy.try_shutdown(context=context)


@pytest.fixture
def learner(graph, client, wait_for):
    """The client, what it hears from now on (announced models, samples) and the graph's
    folder."""
    heard = {'models': [], 'samples': []}
    latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
    subscriptions = [
        client.create_subscription(ModelInfo, topics.MODEL, heard['models'].append, latched),
        client.create_subscription(DeflectionSample, topics.SAMPLES, heard['samples'].append,
                                   100)]
    wait_for(lambda: all(s.get_publisher_count() for s in subscriptions), 10.0,
             "the learner's model and sample publishers")
    yield client, heard, graph
    for subscription in subscriptions:
        client.destroy_subscription(subscription)


def test_collect_train_and_announce(learner):
    client, heard, _ = learner
    name = fresh('b')
    result = client.collect(10, region='B', dataset=name, seed=3, timeout=120)
    assert result.error_code == CollectSamples.Result.SUCCESSFUL, result.error_string
    assert result.collected + result.skipped == 10 and result.collected >= 9
    dataset = load_dataset(result.dataset_path)
    assert len(dataset) == result.total == result.collected
    joints, deflections, payload = dataset.arrays()
    assert (abs(deflections[:, 1]) > 2e-3).all()              # region B sags 6-14 mm
    deadline = time.monotonic() + 5
    while len(heard['samples']) < result.collected and time.monotonic() < deadline:
        client.spin_once(0.05)
    assert len(heard['samples']) == result.collected

    trained = client.train('mlp', dataset=name)
    assert trained.success, trained.message
    assert trained.metrics.samples == len(dataset) and trained.metrics.max_error_y > 0
    deadline = time.monotonic() + 5     # (the latched topic may hold an earlier test's model)
    while (not any(m.version == trained.model_version for m in heard['models'])
           and time.monotonic() < deadline):
        client.spin_once(0.05)
    assert heard['models'][-1].version == trained.model_version
    assert heard['models'][-1].dataset_hash == dataset.hash
    assert client.wait_for_model(trained.model_version, timeout=10).path == trained.model_path

    for kind, settings, dataset_name in (('svm', {}, name), ('mlp', {'hidden': 'ten'}, name),
                                         ('mlp', {}, 'missing')):
        failed = client.train(kind, settings, dataset=dataset_name)
        assert not failed.success and failed.message
    client.spin_once(0.2)
    assert heard['models'][-1].version == trained.model_version   # previous model stays


def test_invalid_collection_goal_is_refused(learner):
    client, _, _ = learner
    for kwargs in ({'count': 0}, {'count': 3, 'region': 'Z'}, {'count': 3, 'strategy': 'x'}):
        result = client.collect(timeout=30, **kwargs)
        assert result.error_code == CollectSamples.Result.INVALID_GOAL and result.error_string


def test_cancel_keeps_every_collected_sample(learner):
    client, _, _ = learner
    outcome, progress = {}, []
    thread = threading.Thread(target=lambda: outcome.setdefault('result', client.collect(
        30, region='A', dataset=fresh('c'), timeout=120,
        feedback=lambda fb: progress.append(fb.k))))
    thread.start()
    deadline = time.monotonic() + 60
    while len(progress) < 3 and time.monotonic() < deadline:
        time.sleep(0.05)
    client.cancel()
    thread.join(timeout=60)
    result = outcome['result']
    assert result.error_code == CollectSamples.Result.CANCELED
    assert 3 <= result.collected < 30
    assert len(load_dataset(result.dataset_path)) == result.collected == result.total


@pytest.fixture
def trainer(graph, good, client):
    """The client, and the graph's folder (datasets ``good`` and ``no_version``)."""
    return client, graph


@pytest.fixture
def second_client(graph, domain_id):
    """Another client of the graph, ready."""
    made, context = open_client(domain_id, 'second_client')
    try:
        made.wait_until_ready(timeout=30.0)
        yield made
    finally:
        made.destroy_node()
        rclpy.try_shutdown(context=context)


def test_damaged_files_or_outside_name_are_refused_and_the_learner_serves_on(trainer,
                                                                          write_dataset):
    client, root = trainer
    models = root / 'models'
    (models / 'current.json').write_text(DAMAGED_RECORD)   # as when the learner started
    newest = max(versions_on_disk(models))                  # v3 (an older model), or later
    result = client.collect(3, dataset='no_version', timeout=30)
    assert result.error_code == CollectSamples.Result.INVALID_GOAL
    assert 'no valid version' in result.error_string, result.error_string
    failed = client.train('rbf', dataset='no_version', timeout=60)
    assert not failed.success and 'no valid version' in failed.message, failed.message
    outside = fresh('outside')
    write_dataset(root / f'{outside}.jsonl')
    escaped = client.train('rbf', dataset=f'../{outside}', timeout=60)
    assert not escaped.success and 'dataset name' in escaped.message, escaped.message
    trained = client.train('rbf', dataset='good', timeout=60)
    assert trained.success, trained.message
    assert trained.model_version == str(newest + 1)          # not the damaged record's next
    assert (models / 'good-rbf-v3.model').read_bytes() == b'an older model'   # v3 intact


def test_training_is_refused_while_a_collection_runs(trainer, second_client):
    client, _ = trainer
    run = client.collect_async(100, region='B', dataset=fresh('busy'),   # far more poses than
                               timeout=120)                                # it runs
    try:
        deadline = time.monotonic() + 20
        while run.feedback() is None and not run.done() and time.monotonic() < deadline:
            time.sleep(0.05)                                    # a pose done: it runs
        assert run.feedback() is not None and not run.done(), 'the collection did not start'
        refused = second_client.train('rbf', dataset='good', timeout=60)
        assert not refused.success and 'busy' in refused.message, refused.message
    finally:
        run.cancel()
    assert run.result().error_code == CollectSamples.Result.CANCELED


def test_an_outlier_is_excluded_and_reported(trainer, write_dataset):
    client, root = trainer
    name = fresh('outlier')
    write_dataset(root / 'data' / f'{name}.jsonl', count=30, bad=11)
    trained = client.train('', dataset=name, timeout=120)      # the learner's default
    assert trained.success, trained.message
    assert list(trained.metrics.excluded_samples) == [11]
    assert trained.metrics.samples == 29 and trained.metrics.selected_settings
    assert 0 < trained.metrics.max_slope < 0.5
    model = load_model(trained.model_path)
    assert model.kind == 'auto' and model.metadata['metrics']['excluded_samples'] == [11]


def test_models_carry_provenance_and_can_be_rolled_back(trainer):
    client, root = trainer
    models = root / 'models'
    newest = max(versions_on_disk(models))                  # 3 in a fresh graph
    first = client.train('rbf', dataset='good', timeout=60)
    second = client.train('rbf', {'smoothing': 0.01}, dataset='good', timeout=60)
    assert first.success and second.success, (first.message, second.message)
    assert read_current(models)['version'] == second.model_version == str(newest + 2)
    back = client.use_model(first.model_version)
    assert back.success, back.message
    assert back.model.version == str(newest + 1) and back.model.dataset == 'good'
    assert list(back.model.payloads) == [0.0] and back.model.warning == ''
    assert back.model.metrics.samples == first.metrics.samples
    assert read_current(models)['version'] == str(newest + 1)
    for version, why in (('3', 'not a model file'), ('99', 'no model version 99'),
                         ('../x', 'must be a number')):
        refused = client.use_model(version)
        assert not refused.success and why in refused.message, refused.message
    assert read_current(models)['version'] == str(newest + 1)
