"""Demand: inputs wanted while any watched output has a subscriber."""
from types import SimpleNamespace

from flexarm_core.demand import Demand, on_matched


def test_wanted_from_the_first_subscriber_of_any_output_to_the_last_one_leaving():
    changes: list[bool] = []
    demand = Demand(changes.append)
    demand.update('tf', 1)
    demand.update('tf', 2)                 # more subscribers: no news
    demand.update('measured_tip', 1)
    demand.update('tf', 0)
    assert changes == [True] and demand.wanted
    demand.update('measured_tip', 0)
    assert changes == [True, False] and not demand.wanted
    demand.update('tf', 0)                 # still nobody
    assert changes == [True, False]


def test_a_matched_event_feeds_every_demand_of_its_output():
    joints, tips = [], []
    callback = on_matched('tf', Demand(joints.append), Demand(tips.append))
    callback(SimpleNamespace(current_count=1))
    callback(SimpleNamespace(current_count=0))
    assert joints == tips == [True, False]
