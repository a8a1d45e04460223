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
    assert {"starting", "error", "inactive"} <= used  # sees the calls
    from rheo_shaping.planning.run_state import reported_state
    from rheo_shaping.planning.states import STREAM_STATES
    for st in (None, *STREAM_STATES):               # the run's states, as reported
        for aborted, now in itertools.product((False, True), (0, 100 * NS)):
            used.add(reported_state(st, aborted, now, 0, 60.0))
    used.discard(None)
    assert {"done", "running", "holding", "waiting"} <= used
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


def heartbeat(**change):
    from rheo_shaping.planning.run_state import Heartbeat
    base = dict(required=True, received_ns=NS, now_ns=NS + NS // 4, timeout=0.5, ready=True)
    return Heartbeat(**{**base, **change})


@pytest.mark.parametrize("change, why", [
    ({}, ""),
    ({"required": False, "received_ns": None, "ready": False}, ""),
    ({"received_ns": None}, "no ready heartbeat from the monitor yet"),
    ({"now_ns": NS + NS // 2}, ""),                                   # exactly the timeout
    ({"now_ns": NS + NS // 2 + NS // 100}, "no ready heartbeat from the monitor for 0.51 s"),
    ({"ready": False}, "the monitor reports not ready"),
    ({"untrusted": "a second publisher of /shaping/ready: /rogue"},
     "a second publisher of /shaping/ready: /rogue"),
])
def test_the_interlock_wants_a_fresh_ready_heartbeat_of_the_trusted_writer(change, why):
    from rheo_shaping.planning.run_state import interlock
    untrusted = change.pop("untrusted", "")
    asked = []

    def trust() -> str:
        asked.append(True)
        return untrusted
    assert interlock(heartbeat(**change), trust) == (not why, why)
    # the writer's trust (a graph query) is asked only once everything else holds
    assert bool(asked) == (why in ("", untrusted) and change.get("required", True))


def test_start_and_reset_replies():
    from rheo_shaping.planning.run_state import reset_refusal, start_reply
    assert start_reply("running", None, True) == (False, "already started (running); "
                                                  "~/reset first")
    assert start_reply(None, "monitor: F > 0.93 N", True) == (
        False, "aborted (monitor: F > 0.93 N); ~/reset first")
    assert start_reply(None, None, True) == (True, "start requested: waiting for the interlock")
    assert start_reply(None, None, False)[1].endswith(
        "(starting up: checking that no other planner runs)")
    for state in ("running", "stopping", "retracting"):
        assert reset_refusal(state) == f"refused: the tool is moving ({state})"
    for state in (None, "done", "holding", "idle"):
        assert reset_refusal(state) == ""


def test_the_executed_time_is_the_poses_never_after_the_newest_setpoint():
    from rheo_shaping.planning.run_state import executed_ns
    assert executed_ns(now_ns=9, last_ns=None, pose_ns=None, t0_ns=None) == 9
    assert executed_ns(now_ns=9, last_ns=7, pose_ns=None, t0_ns=1) == 7
    assert executed_ns(now_ns=9, last_ns=7, pose_ns=0, t0_ns=1) == 7      # before the run
    assert executed_ns(now_ns=9, last_ns=7, pose_ns=5, t0_ns=1) == 5
    assert executed_ns(now_ns=9, last_ns=7, pose_ns=8, t0_ns=1) == 7


def test_the_reported_state_is_done_only_once_the_process_is_over():
    from rheo_shaping.planning.run_state import reported_state
    assert reported_state(None, False, 0, None, 60.0) is None
    assert reported_state(None, True, 0, None, 60.0) == "holding"
    assert reported_state("idle", False, 0, 0, 60.0) == "waiting"
    assert reported_state("stopping", True, 0, 0, 60.0) == "stopping"
    t0 = 3 * NS
    assert reported_state("done", False, t0 + 60 * NS - 2, t0, 60.0) == "running"
    assert reported_state("done", False, t0 + 60 * NS - 1, t0, 60.0) == "done"


def test_the_lead_reasons_name_the_figures():
    from rheo_shaping.planning.run_state import lead_wait, start_lead
    assert start_lead(5 * NS, None, 0.5).startswith("no /tool/pose yet")
    assert start_lead(5 * NS, 5 * NS - NS // 2, 0.5) == ""
    assert start_lead(5 * NS, 4 * NS, 0.5).startswith(
        "/clock runs 1.000 s ahead of /tool/pose, beyond max_lead 0.5 s")
    assert lead_wait(5 * NS, 5 * NS, 4 * NS, 0.5) == ""
    assert lead_wait(5 * NS + 1, 5 * NS, 4 * NS, 0.5) == (
        "set-points wait for the tool: /tool/pose at 4.000 s, clock 5.000 s (max_lead 0.5 s)")


def test_an_abort_stops_from_the_executed_time_and_sends_again_from_there():
    """The stop starts at the executed pose's time on the plan's exact state there: the
    set-points sent after it are superseded, the first one sent again is at that time, and
    the stream stays continuous (the stop's first set-point is the plan's at that time)."""
    import numpy as np

    from rheo_shaping.planning.plans import MotionLimits, Waypoint, plan_waypoints
    from rheo_shaping.planning.run_state import stop_run
    from rheo_shaping.planning.stopping import TrajectoryStreamer
    plan = plan_waypoints((0.0, 0.1), [Waypoint(0.1, 0.1)], MotionLimits(0.02, 0.2, 2.0))
    assert stop_run(None, None, "x", 0) is None                 # nothing runs: only latched
    st = TrajectoryStreamer(home_xz=(0.0, 0.2))
    st.start(plan, 0.0)
    g = SetpointGrid(0, NS // 50)
    for t in g.due(2 * NS, 10 * NS, sim_time=False):            # 2 s sent
        st.setpoint(t / NS)
    before = plan.sample(1.5)[0]
    sends, what = stop_run(st, g, "monitor: F > threshold", int(1.5 * NS))
    assert sends == [int(1.5 * NS)]
    assert what.startswith("stopping from running at 1.500000 s, at rest in ")
    assert what.endswith(", then retracting to home")
    assert np.allclose(st.setpoint(1.5)[0], before, atol=1e-12)
    assert st.state == "stopping" and st.abort_reason == "monitor: F > threshold"
    # a second abort changes nothing (latched)
    assert stop_run(st, g, "again", int(1.6 * NS)) is None


def test_the_start_inputs_ask_the_node_only_what_matters():
    """The graph queries and the node's checks are asked only when a start is wanted and
    no abort is latched, the checks only behind the interlock, the lead once the clock
    runs; the pose is unknown only if a publisher of it exists."""
    from rheo_shaping.planning.run_state import StartFacts, start_inputs
    asked: list[str] = []

    def ask(name, value):
        def f(*_):
            asked.append(name)
            return value
        return f

    facts = StartFacts(aborted=False, autostart=False, start_requested=False, pose_known=False,
                       hold_known=False, hold_ns=None, pose_ns=None, now_ns=5 * NS,
                       monitor_ok=True)
    calls = (ask("pubs", 1), ask("away", "far"), ask("refusal", ""), ask("lead", ""),
             ask("subs", 1))
    i = start_inputs(facts, *calls)
    assert asked == [] and not i.wants_start and start_decision(i)[0] == "idle"
    i = start_inputs(replace(facts, autostart=True, aborted=True), *calls)
    assert asked == [] and start_decision(i)[0] == "holding"
    i = start_inputs(replace(facts, autostart=True), *calls)
    assert asked == ["pubs", "away", "refusal", "lead", "subs"] and i.pose_unknown
    assert start_decision(i)[0] == "waiting_for_pose"
    asked.clear()
    i = start_inputs(replace(facts, start_requested=True, pose_known=True, monitor_ok=False),
                     *calls)
    assert asked == ["away", "subs"] and not i.pose_unknown
    assert start_decision(i)[0] == "waiting_for_monitor"
    asked.clear()
    i = start_inputs(replace(facts, start_requested=True, pose_known=True, now_ns=0), *calls)
    assert "lead" not in asked and start_decision(i)[0] == "waiting_for_clock"
    # after a run: still arriving until the pose is stamped at the last set-point
    after = replace(facts, autostart=True, pose_known=True, hold_known=True, hold_ns=9 * NS)
    assert start_inputs(replace(after, pose_ns=9 * NS - 1), *calls).arriving
    assert not start_inputs(replace(after, pose_ns=9 * NS), *calls).arriving


def test_the_latch_holds_an_abort_until_reset_and_where_the_tool_holds():
    import numpy as np

    from rheo_shaping.planning.plans import MotionLimits, Waypoint, plan_waypoints
    from rheo_shaping.planning.run_state import RunLatch
    from rheo_shaping.planning.stopping import TrajectoryStreamer
    latch = RunLatch()
    assert latch.start_from(np.array([0.1, 0.2])) is None            # before any run: the plan
    assert latch.abort("monitor: F > threshold") and not latch.abort("again")
    assert latch.abort_reason == "monitor: F > threshold"
    # ~/start with the tool away and its pose known: the run approaches from there
    latch.request_start("the tool is 30 mm from home", np.array([0.07, 0.09]))
    assert latch.start_requested and np.array_equal(latch.hold, [0.07, 0.09])
    pose = np.array([0.071, 0.091])
    assert np.array_equal(latch.start_from(pose), pose)              # the measured pose
    assert np.array_equal(latch.start_from(None), [0.07, 0.09])
    # ~/reset after a run: the hold where the stream stands, every latch cleared
    plan = plan_waypoints((0.0, 0.1), [Waypoint(0.1, 0.1)], MotionLimits(0.02, 0.2, 2.0))
    st = TrajectoryStreamer(home_xz=(0.0, 0.2))
    st.start(plan, 0.0)
    st.setpoint(2.0)
    latch.start_failed = "the approach pinches the sheet"
    message = latch.rearm(st, 2 * NS, 3 * NS)
    assert np.allclose(latch.hold, plan.sample(2.0)[0]) and latch.hold_ns == 2 * NS
    assert message == (f"re-armed; the tool holds at ({latch.hold[0]:.4f}, "
                       f"{latch.hold[1]:.4f}) m")
    assert not latch.aborted and latch.abort_reason == "" and not latch.start_requested
    assert latch.start_failed == ""
    assert RunLatch().rearm(None, None, 0) == "re-armed"
