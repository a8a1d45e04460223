"""The planner's run decisions without ROS (rheo_shaping.planning.run_state)."""
from __future__ import annotations

from dataclasses import replace

import pytest

from rheo_shaping.planning.run_state import (MAX_BATCH, SetpointGrid, StartInputs, lead_limit,
                                             running_decision, start_decision)
from rheo_shaping.units import NS

READY = StartInputs(aborted=False, wants_start=True, start_requested=False, pose_unknown=False,
                    tool_away="", monitor_ok=True, refusal="", lead="", now_ns=5 * NS,
                    subscribers=1)


@pytest.mark.parametrize("change, state", [
    ({}, "start"),
    ({"aborted": True}, "holding"),
    ({"wants_start": False}, "idle"),
    ({"pose_unknown": True}, "waiting_for_pose"),
    ({"arriving": True}, "waiting_for_pose"),
    ({"arriving": True, "start_requested": True}, "waiting_for_pose"),
    ({"tool_away": "the tool is 30 mm from home"}, "tool_away"),
    ({"monitor_ok": False}, "waiting_for_monitor"),
    ({"refusal": "the cell differs from the simulator's: ..."}, "waiting_for_cell"),
    ({"refusal": "2 publishers of /clock"}, "waiting"),
    ({"now_ns": 0}, "waiting_for_clock"),
    ({"lead": "/clock runs 1.0 s ahead of /tool/pose"}, "error"),
    ({"subscribers": 0}, "waiting_for_subscriber"),
])
def test_each_reason_not_to_start_has_its_state(change, state):
    assert start_decision(replace(READY, **change))[0] == state


def test_the_order_of_the_reasons():
    """An abort beats everything; a requested start approaches a tool that is away; the
    interlock comes before the node's own checks."""
    assert start_decision(replace(READY, aborted=True, monitor_ok=False))[0] == "holding"
    away = replace(READY, tool_away="away", start_requested=True)
    assert start_decision(away)[0] == "start"
    assert start_decision(replace(READY, monitor_ok=False, refusal="x"))[0] == \
        "waiting_for_monitor"
    assert start_decision(replace(READY, refusal="2 clocks"))[1] == "2 clocks"


def test_a_running_plan_stops_on_a_lost_monitor_unless_its_own_stall_excuses_it():
    assert running_decision(True, False, "", "") == ""
    assert running_decision(False, False, "no heartbeat for 1.2 s", "") == \
        "planner: monitor lost (no heartbeat for 1.2 s)"
    assert running_decision(False, True, "no heartbeat for 1.2 s", "") == ""
    assert running_decision(True, False, "", "2 publishers of /clock") == \
        "planner: 2 publishers of /clock"


def test_the_grid_sends_each_time_once_and_the_clocks_time_on_sim_time():
    g = SetpointGrid(10 * NS, NS // 50)
    assert g.due(10 * NS, 100 * NS, sim_time=True) == [10 * NS]
    got = g.due(10 * NS + NS // 10 + 5, 100 * NS, sim_time=True)
    assert got == [10 * NS + k * NS // 50 for k in range(1, 6)] + [10 * NS + NS // 10 + 5]
    assert g.due(10 * NS + NS // 10 + 5, 100 * NS, sim_time=True) == []       # nothing twice


def test_the_grid_never_passes_the_lead_limit_whatever_the_clock_does():
    """One forged /clock 30 s ahead: the planner sent the next 30 s of plan in 0.2 s wall."""
    t0 = 10 * NS
    g = SetpointGrid(t0, NS // 50)
    limit = lead_limit(t0, pose_ns=t0, max_lead=0.1)
    assert limit == t0 + NS // 10
    got = g.due(t0 + 30 * NS, limit, sim_time=True)
    assert max(got) <= limit and len(got) == 6           # 0.1 s at 50 Hz, and no clock point
    assert lead_limit(t0, pose_ns=None, max_lead=0.1) == limit
    assert lead_limit(t0, pose_ns=t0 - NS, max_lead=0.1) == limit     # pose before the start


def test_a_far_jump_without_a_limit_skips_ahead_in_batches():
    g = SetpointGrid(0, NS // 50)
    got = g.due(10_000 * NS, 10**12 * NS, sim_time=False)
    assert len(got) == MAX_BATCH and g.skipped == 500_001 - MAX_BATCH


def test_rewind_sends_again_from_the_executed_time():
    g = SetpointGrid(0, NS // 50)
    g.due(NS, 10 * NS, sim_time=False)                 # up to 1 s sent
    assert g.rewind(NS // 2 + 7) == [NS // 2 + 7]       # the stop from the executed pose
    want = [NS // 2 + NS // 50, NS // 2 + NS // 25]
    assert g.due(NS // 2 + NS // 25, 10 * NS, sim_time=False) == want


def test_every_state_the_planner_reports_is_in_the_one_vocabulary():
    """The states the planner node sets (its source, read as text) and those start_decision
    returns on any input are the ones planning.states names, so the monitor and the
    recorder know each."""
    import ast
    import itertools
    from pathlib import Path

    import rheo_shaping
    from rheo_shaping.planning.run_state import StartInputs, start_decision
    from rheo_shaping.planning.states import AT_REST, BEFORE_RUN, MOVING, PLANNER_STATES
    pkg = Path(rheo_shaping.__file__).parent
    used = set()
    for module in ("planner.py", "planner_supervision.py", "managed.py"):   # plain, managed
        tree = ast.parse((pkg / "nodes" / module).read_text())
        used |= {c.value for n in ast.walk(tree) if isinstance(n, ast.Call)
                 and getattr(n.func, "attr", "") == "_set_state" and n.args
                 for c in ast.walk(n.args[0]) if isinstance(c, ast.Constant)
                 and isinstance(c.value, str)}
    assert {"starting", "error", "done", "running", "inactive"} <= used  # sees the calls
    for a, w, r, p, m, s, c, n in itertools.product((False, True), repeat=8):
        for refusal in ("", "the cell differs", "two clocks"):
            state, _ = start_decision(StartInputs(
                aborted=a, wants_start=w, start_requested=r, pose_unknown=p,
                tool_away="away" if s else "", monitor_ok=m, refusal=refusal,
                lead="lead" if a and s else "", now_ns=int(c), subscribers=int(n)))
            used.add(state)
    used.discard("start")                                  # a decision, not a state
    assert {"waiting_for_pose", "waiting_for_cell", "waiting_for_subscriber"} <= used
    assert used <= set(PLANNER_STATES), used - set(PLANNER_STATES)
    assert set(BEFORE_RUN) - {"starting", "waiting"} <= used
    assert not set(MOVING) & set(BEFORE_RUN) and not set(AT_REST) & set(MOVING)
