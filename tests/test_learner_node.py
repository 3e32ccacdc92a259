"""Node-level: collect -> train -> model announced and hot-reloaded by the compensator."""
import threading
import time

import pytest
import rclpy
from rclpy.context import Context
from rclpy.qos import QoSDurabilityPolicy, QoSProfile

from flexarm_control import topics
from flexarm_control.client import FlexarmClient
from flexarm_control.dataset import load_dataset
from flexarm_control.model_store import read_current
from flexarm_control.predictors import load_predictor
from flexarm_msgs.action import CollectSamples
from flexarm_msgs.msg import DeflectionSample, ModelInfo

pytestmark = pytest.mark.node


@pytest.fixture
def learner(launch, domain_id, tmp_path):
    launch('flexarm_sim', real_time_factor=10.0)
    launch('flexarm_vision')
    launch('flexarm_learner', data_directory=str(tmp_path / 'data'),
           model_directory=str(tmp_path / 'models'))
    launch('flexarm_compensator')
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    client = FlexarmClient('test_client', context=context)
    heard = {'models': [], 'samples': []}
    latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
    client.create_subscription(ModelInfo, topics.MODEL, heard['models'].append, latched)
    client.create_subscription(DeflectionSample, topics.SAMPLES, heard['samples'].append, 100)
    try:
        client.wait_until_ready(timeout=30.0)
        yield client, heard, tmp_path
    finally:
        client.destroy_node()
        rclpy.try_shutdown(context=context)


def test_collect_train_and_announce(learner):
    client, heard, tmp = learner
    result = client.collect(10, region='B', dataset='b', seed=3, timeout=120)
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

    trained = client.train('mlp', dataset='b')
    assert trained.success, trained.message
    assert trained.metrics.samples == len(dataset) and trained.metrics.max_error_y > 0
    deadline = time.monotonic() + 5
    while not heard['models'] and time.monotonic() < deadline:
        client.spin_once(0.05)
    assert heard['models'][-1].version == trained.model_version
    assert heard['models'][-1].dataset_hash == dataset.hash
    assert client.wait_for_model(trained.model_version, timeout=10).path == trained.model_path

    for kind, settings, dataset_name in (('svm', {}, 'b'), ('mlp', {'hidden': 'ten'}, 'b'),
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
    import threading

    client, _, _ = learner
    outcome, progress = {}, []
    thread = threading.Thread(target=lambda: outcome.setdefault('result', client.collect(
        30, region='A', dataset='c', timeout=120, feedback=lambda fb: progress.append(fb.k))))
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
def bare_learner(launch, domain_id, tmp_path, write_dataset):
    """Simulator and learner only (no camera: a collection waits for tip poses), datasets
    ``good`` and ``no_version`` (header without a version), a model directory whose
    ``current.json`` is damaged beside a model file v3, and two clients."""
    data, models = tmp_path / 'data', tmp_path / 'models'
    data.mkdir()
    models.mkdir()
    (models / 'current.json').write_text('{"version": "2"}')
    (models / 'good-rbf-v3.model').write_bytes(b'an older model')
    write_dataset(data / 'good.jsonl')
    (data / 'no_version.jsonl').write_text('{"format": "flexarm-deflection-dataset"}\n')
    launch('flexarm_sim', real_time_factor=10.0)
    launch('flexarm_learner', data_directory=str(data), model_directory=str(models))
    contexts, clients = [], []
    try:
        for name in ('test_client', 'second_client'):
            contexts.append(Context())
            rclpy.init(context=contexts[-1], domain_id=domain_id)
            clients.append(FlexarmClient(name, context=contexts[-1]))
            clients[-1].wait_until_ready(timeout=30.0, compensator=False)
        yield clients, tmp_path
    finally:
        for client, context in zip(clients, contexts):
            client.destroy_node()
            rclpy.try_shutdown(context=context)


def test_damaged_files_or_outside_name_are_refused_and_the_learner_serves_on(bare_learner,
                                                                          write_dataset):
    (client, _), tmp = bare_learner
    result = client.collect(3, dataset='no_version', timeout=30)
    assert result.error_code == CollectSamples.Result.INVALID_GOAL
    assert 'no valid version' in result.error_string, result.error_string
    failed = client.train('rbf', dataset='no_version', timeout=60)
    assert not failed.success and 'no valid version' in failed.message, failed.message
    write_dataset(tmp / 'outside.jsonl')
    escaped = client.train('rbf', dataset='../outside', timeout=60)
    assert not escaped.success and 'dataset name' in escaped.message, escaped.message
    trained = client.train('rbf', dataset='good', timeout=60)
    assert trained.success, trained.message
    assert trained.model_version == '4'                        # v3 on disk is not overwritten
    assert (tmp / 'models' / 'good-rbf-v3.model').read_bytes() == b'an older model'


def test_training_is_refused_while_a_collection_runs(bare_learner):
    (client, second), _ = bare_learner
    outcome = {}
    thread = threading.Thread(target=lambda: outcome.setdefault(
        'result', client.collect(5, region='B', dataset='c', timeout=120)))
    thread.start()
    try:
        deadline = time.monotonic() + 20
        while client._goal_handle is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert client._goal_handle is not None, 'the collection did not start'
        refused = second.train('rbf', dataset='good', timeout=60)
        assert not refused.success and 'busy' in refused.message, refused.message
    finally:
        client.cancel()
        thread.join(timeout=30)
    assert outcome['result'].error_code == CollectSamples.Result.CANCELED


def test_an_outlier_is_excluded_and_reported(bare_learner, write_dataset):
    (client, _), tmp = bare_learner
    write_dataset(tmp / 'data' / 'outlier.jsonl', count=30, bad=11)
    trained = client.train('', dataset='outlier', timeout=120)      # the learner's default
    assert trained.success, trained.message
    assert list(trained.metrics.excluded_samples) == [11]
    assert trained.metrics.samples == 29 and trained.metrics.selected_settings
    assert 0 < trained.metrics.max_slope < 0.5
    model = load_predictor(trained.model_path)
    assert model.kind == 'auto' and model.metadata['metrics']['excluded_samples'] == [11]


def test_models_carry_provenance_and_can_be_rolled_back(bare_learner):
    (client, _), tmp = bare_learner
    first = client.train('rbf', dataset='good', timeout=60)
    second = client.train('rbf', {'smoothing': 0.01}, dataset='good', timeout=60)
    assert first.success and second.success, (first.message, second.message)
    assert read_current(tmp / 'models')['version'] == second.model_version == '5'
    back = client.use_model(first.model_version)
    assert back.success, back.message
    assert back.model.version == '4' and back.model.dataset == 'good'
    assert list(back.model.payloads) == [0.0] and back.model.warning == ''
    assert back.model.metrics.samples == first.metrics.samples
    assert read_current(tmp / 'models')['version'] == '4'
    for version, why in (('3', 'not a model file'), ('99', 'no model version 99'),
                         ('../x', 'must be a number')):
        refused = client.use_model(version)
        assert not refused.success and why in refused.message, refused.message
    assert read_current(tmp / 'models')['version'] == '4'
