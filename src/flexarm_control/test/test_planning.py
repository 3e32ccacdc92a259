"""Goal planning policy: which plan a goal runs, refusals beyond the learned data (also its
payloads), fallbacks."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from flexarm_control.execution.compensator import Compensator
from flexarm_control.execution.modes import Mode
from flexarm_control.execution.plan_bound import RIGID_ERROR, SiteErrors
from flexarm_control.execution.planning import DataLimits, Planned, Refusal, plan_goal
from flexarm_core.kinematics import ArmGeometry, forward
from flexarm_core.paper import TABLE_10
from flexarm_core.params import load_config
from flexarm_core.regions import regions_from_dict
from flexarm_deflection.at_payload import AtPayload
from flexarm_deflection.predictors import Predictor, make_predictor
from flexarm_deflection.sampling import sample_poses
from flexarm_sim.plant import Plant

TARGET = np.array([1.30, -0.20, math.radians(-61)])          # Table 10, B6
LIMITS = DataLimits(max_distance=3.0, max_std=0.3e-3)


@pytest.fixture(scope='module')
def world():
    """The compensator and a plant with the masses the robot description gives (what the
    grey-box knows): planning is tested, not the mass model (test_greybox_predictor)."""
    config = load_config('arm.yaml', 'sim.yaml', 'compensator.yaml',
                         node_name='flexarm_compensator')
    geometry = ArmGeometry.from_dict(config['arm'])
    return Compensator(geometry, config['compensation']), Plant.from_dict(
        {**config['plant'], **config['arm']['inertia']}, geometry)


def model(plant: Plant, distance: float = 0.5, std: float = 0.0, predict=None,
          bound: tuple[float, float] = (1e-5, 1e-5), prior: float = 0.0):
    """A stand-in predictor: the plant's deflection, a fixed distance, std, 95 % bound and
    prior std (of x)."""
    return SimpleNamespace(predict=predict or plant.deflection,
                           data_distance=lambda q: distance, position_std=lambda q: std,
                           error_bound=lambda q: np.array(bound),
                           prior_std=lambda q: np.array([prior, 0.0, 0.0]))


def test_rigid_uses_no_model(world):
    compensator, _ = world
    planned = plan_goal(compensator, 'rigid', TARGET, None, LIMITS)
    assert isinstance(planned, Planned) and planned.plan.iterations == 0
    assert planned.data_distance == 0 and not planned.note


def test_predictive_inside_the_data_runs_without_a_note(world):
    compensator, plant = world
    planned = plan_goal(compensator, 'predictive', TARGET, model(plant, 0.7, 1e-4), LIMITS)
    assert isinstance(planned, Planned) and not planned.note
    assert planned.data_distance == 0.7 and planned.prediction_std == 1e-4
    assert np.hypot(*(plant.pose(planned.plan.joints) - TARGET)[:2]) < 2e-6


@pytest.mark.parametrize('distance, std, words', [
    (5.0, 0.0, 'sample spacings'), (0.5, 0.6e-3, 'the model is unsure there')])
def test_predictive_beyond_the_data_is_refused_unless_allowed(world, distance, std, words):
    compensator, plant = world
    predictor = model(plant, distance, std)
    refused = plan_goal(compensator, 'predictive', TARGET, predictor, LIMITS)
    assert isinstance(refused, Refusal) and refused.code == 'outside_learned_data'
    assert words in refused.reason
    allowed = plan_goal(compensator, 'predictive', TARGET, predictor, LIMITS,
                        allow_extrapolation=True)
    assert isinstance(allowed, Planned) and allowed.note.startswith('warning:')
    assert allowed.plan.iterations >= 1
    closed = plan_goal(compensator, 'closed_loop', TARGET, predictor, LIMITS)
    assert isinstance(closed, Planned) and closed.plan.iterations == 0
    assert 'started from the rigid solution' in closed.note


def test_without_a_model_closed_loop_starts_from_the_rigid_plan(world):
    compensator, _ = world
    refused = plan_goal(compensator, 'predictive', TARGET, None, LIMITS)
    assert isinstance(refused, Refusal) and refused.code == 'no_model'
    closed = plan_goal(compensator, 'closed_loop', TARGET, None, LIMITS)
    assert isinstance(closed, Planned) and closed.note.startswith('no trained model')
    np.testing.assert_allclose(closed.plan.joints, compensator.rigid(TARGET).joints)


@pytest.mark.parametrize('distance, code', [(0.5, 'unreachable'),
                                            (5.0, 'outside_learned_data')])
def test_a_plan_the_solver_cannot_find(world, distance, code):
    compensator, plant = world
    geometry = compensator.geometry
    flat = lambda q: np.stack([0 * q[..., 0], -forward(geometry, q)[..., 1] - 0.3,  # noqa
                               0 * q[..., 0]], axis=-1)
    refused = plan_goal(compensator, 'predictive', TARGET, model(plant, distance, predict=flat),
                        LIMITS)
    assert isinstance(refused, Refusal) and refused.code == code
    assert 'no solution' in refused.reason
    closed = plan_goal(compensator, 'closed_loop', TARGET, model(plant, distance, predict=flat),
                       LIMITS)
    assert isinstance(closed, Planned) and closed.note.startswith('prediction failed')


def test_unknown_mode(world):
    with pytest.raises(ValueError, match='unknown mode'):
        plan_goal(world[0], 'teleport', TARGET, None, LIMITS)


@pytest.fixture(scope='module')
def at_0_kg(world) -> dict[tuple[str, str], Predictor]:
    """(kind, region) -> a model of the learner's settings trained on 30 samples of the plant
    at 0 kg (the payload recorded with each, as the learner passes it)."""
    compensator, plant = world
    regions = regions_from_dict(load_config('learner.yaml',
                                            node_name='flexarm_compensator')['regions'])
    models = {}
    for region in ('A', 'B'):
        joints = sample_poses(compensator.geometry, regions[region], 30, 'sobol', 0)[1]
        for kind in ('gp', 'mlp', 'greybox'):
            models[kind, region] = make_predictor(kind).fit(joints, plant.deflection(joints),
                                                            np.zeros(len(joints)))
    return models


@pytest.mark.parametrize('kind', ['gp', 'mlp'])
def test_a_model_that_cannot_carry_the_payload_is_refused_at_another(world, at_0_kg, kind):
    compensator, _ = world
    model = at_0_kg[kind, 'B']
    heavy = AtPayload(model, 5.0)
    refused = plan_goal(compensator, 'predictive', TARGET, heavy, LIMITS,
                        trained_payloads=[0.0])
    assert isinstance(refused, Refusal) and refused.code == 'outside_learned_data'
    assert 'trained at payloads [0] kg, cannot predict at 5 kg' in refused.reason
    assert 'collect samples at this payload, or allow extrapolation' in refused.reason
    allowed = plan_goal(compensator, 'predictive', TARGET, heavy, LIMITS,
                        allow_extrapolation=True, trained_payloads=[0.0])
    assert isinstance(allowed, Planned) and allowed.uses_model
    assert allowed.note.startswith('warning:') and 'cannot predict at 5 kg' in allowed.note
    closed = plan_goal(compensator, 'closed_loop', TARGET, heavy, LIMITS,
                       trained_payloads=[0.0])
    assert isinstance(closed, Planned) and 'started from the rigid solution' in closed.note
    # within the tolerance (10 g) it is the trained payload; unknown payloads: not checked
    for payload, trained in ((0.0, [0.0]), (0.008, [0.0]), (5.0, ())):
        planned = plan_goal(compensator, 'predictive', TARGET, AtPayload(model, payload),
                            LIMITS, trained_payloads=trained)
        assert isinstance(planned, Planned) and not planned.note, (payload, trained)
    assert isinstance(plan_goal(compensator, 'predictive', TARGET, AtPayload(model, 0.02),
                                LIMITS, trained_payloads=[0.0]), Refusal)


@pytest.mark.parametrize('target', TABLE_10, ids=lambda t: t.name)
def test_the_greybox_trained_at_0_kg_reaches_a_goal_at_5_kg(world, at_0_kg, target):
    """Planned without a note; the sagging arm's tip within 1 mm of the target (without the
    payload in the moments it missed by 11-18 mm; measured: A 0.02 mm, B 0.35-0.61 mm,
    where joint 4's moment changes sign and its two compliances of Table 5 are one)."""
    compensator, plant = world
    planned = plan_goal(compensator, 'predictive', target.pose,
                        AtPayload(at_0_kg['greybox', target.region], 5.0), LIMITS,
                        trained_payloads=[0.0])
    assert isinstance(planned, Planned) and not planned.note
    reached = plant.with_payload(5.0).pose(planned.plan.joints)
    assert np.hypot(*(reached - target.pose)[:2]) < 1e-3


SITE = SiteErrors(np.array([2.9e-5, 5e-6, 2.9e-5, 2.9e-5]), (2e-5, 3.5e-5), (5e-6, 1.3e-5), 1.2e-5)
TOLERANCE = (5e-4, 1e-2)


def test_every_plan_states_its_bound(world):
    """PREDICTIVE: the model's and the site's in quadrature; CLOSED_LOOP: the tolerance and the
    camera; RIGID: what it leaves of the sag besides, or the paper's rigid error unmodelled."""
    compensator, plant = world
    predictor = model(plant, bound=(3e-4, 2e-4))
    predictive = plan_goal(compensator, 'predictive', TARGET, predictor, LIMITS, site=SITE)
    site = SITE.at(compensator.geometry, predictive.plan.joints)
    assert predictive.bound == pytest.approx(tuple(np.hypot((3e-4, 2e-4), site)))
    assert site[0] > 1.731 * 2.9e-5 * 1.6 and predictive.mode == Mode.PREDICTIVE
    closed = plan_goal(compensator, 'closed_loop', TARGET, predictor, LIMITS, site=SITE,
                       tolerance=TOLERANCE)
    assert TOLERANCE[0] < closed.bound[0] < TOLERANCE[0] + 1e-4
    rigid = plan_goal(compensator, 'rigid', TARGET, predictor, LIMITS, site=SITE)
    sag = plant.deflection(rigid.plan.joints)
    model_there = np.hypot((3e-4, 2e-4), SITE.at(compensator.geometry, rigid.plan.joints))
    assert rigid.bound[0] == pytest.approx(model_there[0] + np.hypot(sag[0], sag[1]))
    assert rigid.bound[0] > 5e-3          # the sag it leaves: millimetres
    assert plan_goal(compensator, 'rigid', TARGET, None, LIMITS).bound == RIGID_ERROR


def test_a_predictive_goal_its_bound_exceeds_is_refused_with_what_would_help(world):
    compensator, plant = world
    payload = model(plant, bound=(2e-3, 1e-4), prior=8e-4)
    refused = plan_goal(compensator, 'predictive', TARGET, payload, LIMITS, site=SITE,
                        tolerance=TOLERANCE)
    assert isinstance(refused, Refusal) and refused.code == 'bound' and refused.bound[0] > 2e-3
    assert '2.00' in refused.reason and 'exceeds the tolerance 0.500 mm' in refused.reason
    assert 'collect samples carrying it' in refused.reason
    unsure = plan_goal(compensator, 'predictive', TARGET, model(plant, bound=(2e-3, 1e-4)),
                       LIMITS, site=SITE, tolerance=TOLERANCE)
    assert 'collect more samples here' in unsure.reason
    allowed = plan_goal(compensator, 'predictive', TARGET, payload, LIMITS, True, site=SITE,
                        tolerance=TOLERANCE)
    assert isinstance(allowed, Planned) and allowed.bound[0] > 2e-3
    unknown = plan_goal(compensator, 'predictive', TARGET, model(plant, bound=(math.nan,) * 2),
                        LIMITS, site=SITE, tolerance=TOLERANCE)
    assert isinstance(unknown, Refusal) and 'states no error bound' in unknown.reason
    assert isinstance(plan_goal(compensator, 'predictive', TARGET, payload, LIMITS, site=SITE),
                      Planned)       # no tolerance: nothing to check


def test_auto_runs_predictive_within_the_tolerance_and_closed_loop_beyond_it(world):
    compensator, plant = world
    tight = plan_goal(compensator, 'auto', TARGET, model(plant), LIMITS, site=SITE,
                      tolerance=TOLERANCE)
    assert tight.mode == Mode.PREDICTIVE and tight.note.startswith('AUTO ran PREDICTIVE')
    assert tight.plan.iterations >= 1
    loose = plan_goal(compensator, 'auto', TARGET, model(plant, bound=(2e-3, 1e-4)), LIMITS,
                      site=SITE, tolerance=TOLERANCE)
    assert loose.mode == Mode.CLOSED_LOOP and loose.note.startswith('AUTO ran CLOSED_LOOP')
    assert 'exceeds the tolerance' in loose.note and loose.bound[0] < 6e-4
    alone = plan_goal(compensator, 'auto', TARGET, None, LIMITS, site=SITE, tolerance=TOLERANCE)
    assert alone.mode == Mode.CLOSED_LOOP and 'no trained predictor' in alone.note
    with pytest.raises(ValueError, match='AUTO needs'):
        plan_goal(compensator, 'auto', TARGET, model(plant), LIMITS)


def test_a_model_run_at_a_payload_it_cannot_predict_at_states_no_bound(world):
    compensator, plant = world
    blind = SimpleNamespace(**vars(model(plant)), payload=5.0, carried=False)
    planned = plan_goal(compensator, 'predictive', TARGET, blind, LIMITS, True,
                        trained_payloads=[0.0], site=SITE)
    assert isinstance(planned, Planned) and all(math.isnan(b) for b in planned.bound)
    closed = plan_goal(compensator, 'closed_loop', TARGET, blind, LIMITS, trained_payloads=[0.0],
                       site=SITE, tolerance=TOLERANCE)
    assert closed.bound[0] < 6e-4
