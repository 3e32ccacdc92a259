"""The domain's one /clock among several simulators (pure policy)."""
import pytest

from flexarm_sim.clock_share import FOLLOW, OWN, REMEMBERED, ClockShare, yields

ARM1, ARM2 = '/arm1/flexarm_sim', '/arm2/flexarm_sim'


def follower(silence: float = 1.0, started: float = 100.0) -> ClockShare:
    return ClockShare(FOLLOW, ARM2, silence, margin=80, started=started, publisher=ARM1)


def test_two_owners_decide_alike_which_one_keeps_the_clock() -> None:
    # far apart: the one behind yields (it follows forward), whatever the names
    assert yields(own_tick=0, own_name=ARM1, other_tick=15000, other_name=ARM2, margin=80)
    assert not yields(own_tick=15000, own_name=ARM2, other_tick=0, other_name=ARM1, margin=80)
    # close together: the name that sorts later yields, seen from either side
    assert yields(own_tick=1000, own_name=ARM2, other_tick=1040, other_name=ARM1, margin=80)
    assert yields(own_tick=1040, own_name=ARM2, other_tick=1000, other_name=ARM1, margin=80)
    assert not yields(own_tick=1000, own_name=ARM1, other_tick=1040, other_name=ARM2, margin=80)


def test_a_follower_takes_over_a_silent_clock_from_the_time_it_reached() -> None:
    share = follower()
    assert not share.silent(100.5)                    # silent since it began following
    assert share.silent(101.5)
    assert not share.heard(102.0, tick=4000, own_tick=4000)
    assert not share.silent(102.9) and share.silent(103.1)
    share.take_over(4000)
    assert share.role == OWN and not share.silent(200.0)
    assert share.text(0.01) == f'publishes /clock, taken over at 40.000 s from {ARM1}'


def test_a_clock_gone_back_is_a_restarted_owner_and_is_taken_over() -> None:
    share = follower()
    assert not share.heard(100.0, tick=4000 - 80, own_tick=4000)     # within the margin
    assert share.heard(100.0, tick=40, own_tick=4000)


def test_an_owner_tells_its_own_clock_from_another_by_the_ticks_it_published() -> None:
    share = ClockShare(OWN, ARM1, 1.0, margin=80, started=0.0)
    for tick in range(40, 40 * (REMEMBERED + 2), 40):
        share.published(tick)
    assert share.is_own(40 * (REMEMBERED + 1)) and not share.is_own(40)   # only the latest
    assert not share.is_own(1234)
    share.follow(ARM2, 50.0)
    assert share.role == FOLLOW and share.publisher == ARM2
    # its own last ticks, arriving after it yielded, are not the new publisher's clock gone back
    assert share.is_own(40 * REMEMBERED) and not share.is_own(1234)
    assert share.text(0.01) == f'follows the /clock of {ARM2}'
    assert share.silent(51.5)
    share.take_over(5000)
    assert not share.is_own(40 * REMEMBERED)        # a new ownership: new ticks


def test_an_unknown_role_is_refused() -> None:
    with pytest.raises(ValueError, match='clock_source must be one of'):
        ClockShare('lead', ARM1, 1.0, 80, 0.0)
