"""Simulated time of the sim node: exact per tick, never stepping back."""
import pytest

from flexarm_sim.sim_node import tick_time


@pytest.mark.parametrize('rate', [100.0, 300.0, 30.0, 1000.0])
def test_stamps_advance_by_one_period_every_tick(rate: float) -> None:
    stamps = [tick_time(tick, rate) for tick in range(5000)]
    assert stamps[0] == (0, 0)
    assert all(0 <= nanosec < 1_000_000_000 for _, nanosec in stamps)
    assert all(a < b for a, b in zip(stamps, stamps[1:]))
    ns = [sec * 1_000_000_000 + nanosec for sec, nanosec in stamps]
    period = 1e9 / rate
    assert all(abs(b - a - period) <= 1 for a, b in zip(ns, ns[1:]))
    assert tick_time(3 * round(rate), rate) == (3, 0)
