"""One commander (rheo_shaping.safety.command_gate.CommandGate), without ROS."""
from __future__ import annotations

import numpy as np
import pytest

from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import movement_plan
from rheo_shaping.safety.command_gate import GRAPH_WAIT, CommandGate, Publisher, ToolLimits
from rheo_shaping.units import NS

PLANNER = Publisher("/planner", "01.0f.aa")
ROGUE = Publisher("/rogue", "01.0f.bb")
LIMITS = ToolLimits(max_speed=0.01, max_accel=0.1, max_jump=0.005)


def test_binds_to_the_one_publisher_and_refuses_a_second_one():
    g = CommandGate(LIMITS)
    assert g.source([PLANNER], 1) == "" and g.bound == PLANNER
    assert g.source([PLANNER], 2) == ""
    why = g.source([PLANNER, ROGUE], 3)
    assert "a second publisher of /tool/command: /rogue (01.0f.bb)" in why
    assert "bound planner /planner" in why


def test_no_single_publisher_in_the_graph_binds_nothing():
    g = CommandGate(LIMITS)
    assert "0 publishers of /tool/command" in g.source([], 1)
    assert "2 publishers" in g.source([PLANNER, ROGUE], 1) and g.bound is None


def test_set_points_before_their_writer_is_in_the_graph_wait_then_hold():
    g = CommandGate(LIMITS)
    assert g.unbound_wait([], 0.0) == "wait"
    assert g.unbound_wait([], GRAPH_WAIT - 1e-3) == "wait"
    assert g.unbound_wait([], GRAPH_WAIT) == "hold"
    assert g.unbound_wait([PLANNER], GRAPH_WAIT + 10) == "judge"
    assert g.unbound_wait([PLANNER, ROGUE], 0.0) == "judge"   # source() refuses them then


def test_a_sample_out_of_the_bound_writers_sequence_is_another_writer():
    """A rogue writer matched before the graph shows it: its own count starts at 1."""
    g = CommandGate(LIMITS)
    for seq in range(1, 501):
        assert g.source([PLANNER], seq) == ""
    assert "number 1 after 500" in g.source([PLANNER], 1)
    assert g.source([PLANNER], 503) == ""           # a gap (history overflow) is the planner's


def test_a_restarted_planner_is_bound_once_the_old_one_left_the_graph():
    g = CommandGate(LIMITS)
    assert g.source([PLANNER], 900) == ""
    again = Publisher("/planner", "01.0f.cc")
    assert "a second publisher" in g.source([PLANNER, again], 1)   # the dead one lingers
    assert g.source([again], 1) == "" and g.bound == again


def test_the_plan_of_the_default_cell_keeps_limits_set_above_its_own():
    cell = CellParams()
    plan = movement_plan(cell).plan
    mv = cell.movement
    g = CommandGate(ToolLimits(mv.speed * 1.001, mv.accel * 1.001, 0.001))
    t = np.arange(0.0, plan.duration, 0.02)
    pos, _, _ = plan.sample_many(t)
    for ti, (x, z) in zip(t, pos):
        assert g.judge(int(round(ti * NS)) + NS, x, z, pos[0]) == ""


@pytest.mark.parametrize("limit, points, why", [
    ("jump", [(1.0, 0.0), (1.02, 0.006)], "6.000 mm from the one before (max_tool_jump 5 mm)"),
    ("speed", [(1.0, 0.0), (1.1, 0.002)], "20.000 mm/s (max_tool_speed 10 mm/s)"),
    ("accel", [(1.0, 0.0), (1.1, 0.0005), (1.2, 0.0015)],
     "accelerating at 50.000 mm/s^2 (max_tool_accel 49.9 mm/s^2)"),
])
def test_a_set_point_beyond_a_limit_is_named(limit, points, why):
    g = CommandGate(LIMITS if limit != "accel" else ToolLimits(0.02, 0.0499, 0.005))
    reasons = [g.judge(int(t * NS), x, 0.0, (0.0, 0.0)) for t, x in points]
    assert reasons[:-1] == [""] * (len(points) - 1)
    assert why in reasons[-1], reasons[-1]


def test_a_replacement_is_judged_against_what_precedes_it_in_time():
    g = CommandGate(LIMITS)
    for k in range(10):                                 # 1 mm/s along x
        assert g.judge(NS + k * NS // 50, k * 2e-5, 0.0, (0.0, 0.0)) == ""
    # a stop re-planned from t = 1.1 s: replaces the set-points from there on
    assert g.judge(NS + 5 * NS // 50, 5 * 2e-5, 0.0, (0.0, 0.0)) == ""
    assert "from the one before" in g.judge(NS + 6 * NS // 50, 0.01, 0.0, (0.0, 0.0))


def test_the_hold_latches_its_first_reason_until_reset():
    g = CommandGate(LIMITS)
    assert g.hold("monitor: abort") and not g.hold("later")
    assert g.held == "monitor: abort"
    g.reset()
    assert g.held == ""


def test_a_command_without_stamp_or_finite_position_or_in_another_frame_is_ignored():
    from rheo_shaping.safety.command_gate import malformed_setpoint
    assert malformed_setpoint(1, 0.1, 0.2, "cake", "cake") == ""
    assert malformed_setpoint(1, 0.1, 0.2, "", "cake") == ""
    assert malformed_setpoint(0, 0.1, 0.2, "cake", "cake") == (
        "ignored /tool/command with stamp 0 ns at (0.1, 0.2)")
    assert malformed_setpoint(5, float("nan"), 0.2, "cake", "cake").startswith(
        "ignored /tool/command with stamp 5 ns at (nan")
    assert malformed_setpoint(5, 0.1, float("inf"), "cake", "cake") != ""
    assert malformed_setpoint(5, 0.1, 0.2, "world", "cake") == (
        "ignored /tool/command in frame 'world': expected 'cake'")


def test_setpoints_before_the_graph_shows_their_writer_wait_and_are_judged_in_order():
    from rheo_shaping.safety.command_gate import Arrivals
    planner = Publisher("/planner", "01.02")
    rogue = Publisher("/rogue", "09.09")
    a = Arrivals(CommandGate(ToolLimits(0.05, 1.0, 5e-3)))
    graph: list[Publisher] = []
    assert a.offer("p1", 1, 0, lambda: graph) == ([], "")            # no writer shown yet
    assert a.offer("p2", 2, NS // 10, lambda: graph) == ([], "")     # behind it, in order
    assert a.release(NS // 5, graph) == ([], "") and len(a.waiting) == 2
    graph.append(planner)
    assert a.release(NS // 4, graph) == (["p1", "p2"], "") and not a.waiting
    assert a.gate.bound == planner
    assert a.offer("p3", 3, NS, lambda: graph) == (["p3"], "")
    # a sample out of the bound writer's sequence is another writer's
    follow, why = a.offer("x", 2, NS, lambda: graph)
    assert follow == [] and "out of the bound planner's sequence" in why
    # a second writer: refused, named
    graph.append(rogue)
    follow, why = a.offer("y", 4, NS, lambda: graph)
    assert follow == [] and "a second publisher of /tool/command: /rogue" in why
    # the graph never shows a writer: the tool holds after GRAPH_WAIT
    b = Arrivals(CommandGate(ToolLimits(0.05, 1.0, 5e-3)))
    b.offer("q", 1, 0, lambda: [])
    assert b.release(round(GRAPH_WAIT * NS) - 1, []) == ([], "")
    assert b.release(round(GRAPH_WAIT * NS), []) == (
        [], f"set-points from a writer the graph does not show after {GRAPH_WAIT:g} s")
    # nothing is taken while the gate holds
    b.gate.hold("abort: test")
    assert b.offer("r", 2, 0, lambda: [planner]) == ([], "")
