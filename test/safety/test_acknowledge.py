"""The monitor's acknowledgements (rheo_shaping.safety.acknowledge): each judged sample,
withheld after an abort until the planner is off its plan or the hold's limit; and the
simulator's side (MonitorLead): a step waits while ``lead`` samples are unacknowledged."""
from __future__ import annotations

from rheo_shaping.planning.states import BEFORE_RUN
from rheo_shaping.safety.acknowledge import Acknowledgements, MonitorLead
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


def test_a_twin_planners_state_neither_lifts_nor_prevents_the_hold():
    """A second planner starting (then yielding) reports states before a run while the first
    one runs its plan: they are not the running planner's, so they change nothing."""
    for twin_first in (True, False):
        a = Acknowledgements(hold=10.0)
        a.on_planner_state("running")
        a.on_judged(3)
        if twin_first:                              # the twin's state came before the abort
            assert a.on_planner_state("starting") is None
        a.on_abort(0)
        assert a.holding
        for state in BEFORE_RUN:
            assert a.on_planner_state(state) is None and a.holding, state
        assert a.on_judged(4) is None
        assert a.on_planner_state("stopping") == 4 and not a.holding   # the real reaction


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


def _published(lead: MonitorLead, n: int) -> MonitorLead:
    for _ in range(n):
        lead.published()
    return lead


def test_a_step_waits_while_lead_samples_are_unacknowledged():
    ms = NS // 1000
    lead = _published(MonitorLead(lead=2, timeout=0.2), 2)
    assert not lead.behind(0)                   # no acknowledgement yet: no monitor to wait for
    lead.on_checked(1, 0)
    assert not lead.behind(10 * ms)             # 2 out, 1 acknowledged: 1 unacknowledged < 2
    lead.published()
    assert lead.behind(20 * ms)                 # 3 out, 1 acknowledged: 2 unacknowledged
    lead.on_checked(1, 30 * ms)                 # a repeat (the monitor re-sends each period)
    assert lead.behind(40 * ms)
    lead.on_checked(2, 50 * ms)
    assert not lead.behind(60 * ms)
    lead.on_checked(1, 70 * ms)                 # an old one late: the newest still counts
    assert lead.checked == 2 and lead.waits == 2


def test_without_acknowledgements_for_longer_than_the_timeout_steps_go_on():
    ms = NS // 1000
    lead = _published(MonitorLead(lead=1, timeout=0.2), 5)
    lead.on_checked(4, 0)
    t = 0
    while lead.behind(t):                       # checked every 50 ms, as the steps try
        t += 50 * ms
        assert t < NS, "still waiting after 1 s"
    assert 200 * ms < t <= 250 * ms             # the first check past the 0.2 s timeout
    lead.on_checked(5, t)
    lead.published()
    assert lead.behind(t + ms)                  # acknowledgements again: waits again


def test_lead_zero_never_waits():
    lead = _published(MonitorLead(lead=0, timeout=0.2), 10)
    lead.on_checked(1, 0)
    assert not lead.behind(NS // 100) and lead.waits == 0


def test_a_hold_is_not_reset_while_its_cause_persists():
    from rheo_shaping.safety.acknowledge import MonitorLead
    lead = MonitorLead(1, 0.5)
    assert lead.reset_refusal(0, "", "/shaping/checked") == ""       # no monitor ever seen
    rogue = "a second writer of /shaping/checked: /rogue_ack"
    assert lead.reset_refusal(0, rogue, "/shaping/checked") == rogue
    lead.on_checked(1, 0)
    assert lead.reset_refusal(NS // 2, "", "/shaping/checked") == ""
    assert lead.reset_refusal(NS // 2 + 1, "", "/shaping/checked") == (
        "the monitor is lost (no /shaping/checked for over 0.5 s): restart it first")


def test_an_acknowledgement_counts_only_from_the_monitor_and_within_the_samples_sent():
    from rheo_shaping.safety.acknowledge import MonitorLead
    lead = MonitorLead(1, 0.5)
    for _ in range(3):
        lead.published()
    assert lead.refusal(3, "") == ""
    assert lead.refusal(4, "") == "beyond the 3 samples published"
    assert lead.refusal(2, "not the bound monitor's") == "not the bound monitor's"


def test_a_lost_monitor_holds_the_tool_only_once_it_is_commanded():
    """A lapse of the acknowledgements before the first set-point holds nothing (the tool
    stands still; a busy computer's half-second lapse at start-up must not wedge the cell);
    once a set-point came, the same lapse holds with the reason named."""
    lead = MonitorLead(1, 0.5)
    topic = "/shaping/checked"
    assert lead.lost_reason(10 * NS, True, topic) == ""            # no monitor ever seen
    lead.on_checked(1, 0)
    assert lead.lost_reason(NS // 2, True, topic) == ""             # within the timeout
    assert lead.lost_reason(NS // 2 + 1, False, topic) == ""        # lapsed, not commanded
    assert lead.lost_reason(NS // 2 + 1, True, topic) == (
        "monitor lost: no /shaping/checked for over 0.5 s (monitor_timeout)")
    lead.on_checked(2, NS)                                          # the monitor is back
    assert lead.lost_reason(NS + 1, True, topic) == ""
