"""Wall-clock liveness limits grow with the machine's load and the environment's factor."""
import os

import pytest

from flexarm_core import liveness


@pytest.fixture
def machine(monkeypatch):
    """Set the load average and the cores: ``machine(load, cores)``."""
    def set_to(load: float, cores: int) -> None:
        monkeypatch.setattr(os, 'getloadavg', lambda: (load, 0.0, 0.0))
        monkeypatch.setattr(os, 'sched_getaffinity', lambda pid: set(range(cores)))
    return set_to


def test_an_idle_machine_keeps_the_limit(machine, monkeypatch):
    monkeypatch.delenv(liveness.ENV, raising=False)
    machine(0.3, 2)
    assert liveness.limit(3.0) == 3.0


def test_a_loaded_machine_waits_as_many_times_longer_as_processes_share_a_core(machine,
                                                                                monkeypatch):
    monkeypatch.delenv(liveness.ENV, raising=False)
    machine(15.0, 2)
    assert liveness.limit(3.0) == pytest.approx(22.5)


def test_the_environment_is_a_floor_the_load_can_only_raise(machine, monkeypatch):
    monkeypatch.setenv(liveness.ENV, '4')
    machine(2.0, 2)
    assert liveness.limit(3.0) == 12.0
    machine(20.0, 2)
    assert liveness.limit(3.0) == 30.0


@pytest.mark.parametrize('text', ['0', '-1', 'fast'])
def test_a_bad_factor_is_an_error(monkeypatch, text):
    monkeypatch.setenv(liveness.ENV, text)
    with pytest.raises(ValueError):
        liveness.limit(1.0)
