"""The learner's and the compensator's health reports: what each says of its activity,
training, model, model health and goals."""


from flexarm_control.execution.compensator_status import (
    goals_status,
    model_health_status,
    model_status,
)
from flexarm_core.health_report import (
    ERROR,
    OK,
    WARN,
)
from flexarm_deflection.learner_status import learner_statuses
from flexarm_deflection.model_health import RegionHealth
from flexarm_msgs.msg import ModelInfo


def test_the_learner_reports_activity_training_and_model() -> None:
    activity, training, model = learner_statuses(
        'flexarm_learner', 'collecting 3 of 40 into default', True, ('default', 23), None,
        None, '')
    assert activity.name == 'flexarm_learner: activity' and activity.level == OK
    assert activity.message == 'collecting 3 of 40 into default; training'
    assert dict(activity.values)['dataset samples'] == '23'
    assert (training.level, training.message) == (OK, 'no training since start')
    assert model.level == OK and model.message.startswith('no model yet')
    info = ModelInfo(version='4', kind='gp', dataset='default')
    activity, training, model = learner_statuses(
        'flexarm_learner', '', False, None, (False, 'training failed: no dataset'), info, '')
    assert activity.message == 'idle' and dict(activity.values)['dataset'] == ''
    assert (training.level, training.message) == (WARN, 'training failed: no dataset')
    assert (model.level, model.message) == (OK, 'model v4 (gp) announced')
    info.warning = 'trained at payload 0 kg'
    _, training, model = learner_statuses('flexarm_learner', '', False, None,
                                          (True, 'model v4: gp, 40 samples'), info, '')
    assert training.level == OK and model.level == WARN and 'payload 0 kg' in model.message
    *_, model = learner_statuses('flexarm_learner', '', False, None, None, None,
                                 'current.json damaged')
    assert model.level == ERROR and 'current.json damaged' in model.message


def test_the_compensator_reports_model_health_and_goals() -> None:
    name = 'flexarm_compensator'
    assert model_status(name, None, '', None).level == OK
    broken = model_status(name, None, 'the model version 7 could not be loaded', 0.0)
    assert broken.level == ERROR and 'version 7' in broken.message
    info = ModelInfo(version='6', kind='gp')
    assert model_status(name, info, '', 5.0).message == 'model 6 (gp) in use'
    kept = model_status(name, info, 'the model version 7 could not be loaded', None)
    assert kept.level == WARN and dict(kept.values)['payload [kg]'] == 'unknown'

    fine = RegionHealth('A', 5, 0.04e-3, 0.09e-3, 1e-5, False)
    stale = RegionHealth('B', 8, 0.2e-3, 0.3e-3, 2e-5, True)
    assert model_health_status(name, '', [], 1.5e-4, '').message == 'no model in use'
    assert model_health_status(name, '6', [], 1.5e-4, '').message == (
        'model 6: not measured yet')
    ok = model_health_status(name, '6', [fine], 1.5e-4, '')
    assert ok.level == OK and ok.message == 'model 6 fits (5 recent measurements)'
    assert dict(ok.values)['A residual median [mm]'] == '0.04'
    warned = model_health_status(name, '6', [fine, stale], 1.5e-4, 'model 6 is stale in B')
    assert warned.level == WARN and warned.message == 'model 6 is stale in B'
    assert dict(warned.values)['B stale'] == 'yes'
    assert dict(warned.values)['stale residual [mm]'] == '0.15'

    counts = {'succeeded': 3, 'failed': 1, 'canceled': 0}
    idle = goals_status(name, counts, '')
    assert idle.level == OK and idle.message == 'idle, 4 goals run (3 succeeded)'
    assert dict(idle.values)['goals run'] == '4' and dict(idle.values)['goals failed'] == '1'
    assert goals_status(name, counts, 'A1 (predictive)').message == 'executing A1 (predictive)'
