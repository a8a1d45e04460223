"""The monitor's acknowledgements (rheo_shaping.safety.acknowledge): each judged sample,
withheld after an abort until the planner is off its plan or the hold's limit."""
from __future__ import annotations

from rheo_shaping.safety.acknowledge import Acknowledgements
from rheo_shaping.units import NS


def test_each_judged_sample_is_acknowledged_once_in_order():
    a = Acknowledgements(hold=1.0)
    assert a.tick(0) == 0                           # nothing judged: nothing to say
    assert [a.on_judged(s) for s in (1, 2, 2, 1, 3)] == [1, 2, None, None, 3]
    assert a.tick(5) == 3                           # re-published each tick


def test_an_abort_holds_until_the_planner_is_off_its_plan():
    a = Acknowledgements(hold=1.0)
    a.on_planner_state("running")
    assert a.on_judged(7) == 7
    a.on_abort(10 * NS)                             # sample 8 crossed the threshold
    assert a.on_judged(8) is None and a.holding
    assert a.tick(10 * NS + NS // 2) == 7           # still 7 while the abort travels
    assert a.on_planner_state("running") is None    # a repeat of the old state: no release
    assert a.on_planner_state("stopping") == 8 and not a.holding
    assert a.on_judged(9) == 9


def test_the_hold_ends_after_its_limit_without_a_planner_reaction():
    a = Acknowledgements(hold=0.5)
    a.on_planner_state("running")
    a.on_judged(1)
    a.on_abort(0)
    a.on_judged(2)
    assert a.tick(NS // 2 - 1) == 1
    assert a.tick(NS // 2) == 2 and not a.holding


def test_no_hold_without_a_running_planner():
    for state in ("", "waiting_for_monitor", "holding", "done"):
        a = Acknowledgements(hold=1.0)
        if state:
            a.on_planner_state(state)
        a.on_judged(1)
        a.on_abort(0)
        assert a.on_judged(2) == 2 and not a.holding


def test_reset_releases_a_hold():
    a = Acknowledgements(hold=10.0)
    a.on_planner_state("running")
    a.on_abort(0)
    assert a.on_judged(4) is None
    assert a.reset() == 4 and not a.holding
