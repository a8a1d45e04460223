"""One of each (rheo_shaping.safety.one_of_each): who yields to whom, and how long a node
waits before it acts."""
from __future__ import annotations

import math

import pytest

from rheo_shaping.safety.one_of_each import (SETTLE_TIME, UNNAMED_WAIT, Announcement,
                                             commander_refusal, settle_refusal, settle_time,
                                             twin_reason)


def test_the_younger_of_two_same_named_nodes_yields_and_the_older_runs():
    old = Announcement(1_000, 50, "host", "/cell/planner")
    new = Announcement(2_000, 40, "host", "/cell/planner")
    assert "pid 50" in twin_reason(new, old) and "yields" in twin_reason(new, old)
    assert twin_reason(old, new) == ""
    assert twin_reason(old, old) == ""                          # itself
    other = Announcement(500, 1, "host", "/cell/monitor")
    assert twin_reason(new, other) == ""                        # another name
    tie = Announcement(1_000, 60, "host", "/cell/planner")     # same start: smaller pid first
    assert twin_reason(tie, old) and not twin_reason(old, tie)


def test_an_announcement_round_trips_and_anything_else_is_ignored():
    a = Announcement(123, 4, "h", "/planner")
    assert Announcement.parse(a.message()) == a
    for junk in ("", "{}", "not json", '{"start_ns": "x", "pid": 1, "host": "h", "node": "n"}'):
        assert Announcement.parse(junk) is None


@pytest.mark.parametrize("discovery_s, wait_s", [
    (None, SETTLE_TIME), (0.0, SETTLE_TIME), (0.4, SETTLE_TIME), (SETTLE_TIME, SETTLE_TIME),
    (3.5, 3.5), (12.0, 12.0), (math.nan, SETTLE_TIME)])
def test_the_settle_time_grows_with_a_slow_discovery(discovery_s, wait_s):
    assert settle_time(discovery_s) == wait_s


def test_a_node_alone_acts_and_one_that_sees_an_unannounced_twin_waits():
    assert settle_refusal(1, 1, 0, 0, 0.0) == ""                     # alone
    assert settle_refusal(2, 2, 0, 1, 0.0) == ""                     # the other is younger
    # the graph shows a second writer of this name before it shows the node's name
    assert "2 nodes of this name" in settle_refusal(1, 2, 0, 0, 0.0)
    assert "2 nodes of this name" in settle_refusal(2, 1, 0, 0, 0.0)
    assert "~20 s" in settle_refusal(2, 2, 0, 0, 60.0)                # a killed twin's ghost


def test_a_graph_that_still_grows_holds_a_node_back_until_it_holds_still():
    """Discovery brings the nodes one participant at a time: a newcomer acts only once the
    graph's nodes have not changed for its settle time."""
    assert "hold still for 2.0 s" in settle_refusal(1, 1, 0, 0, 5.0, graph_still_s=1.9,
                                                    settle_s=2.0)
    assert settle_refusal(1, 1, 0, 0, 5.0, graph_still_s=2.0, settle_s=2.0) == ""
    # a graph that never holds still (nodes come and go) holds it back for a bounded time
    assert settle_refusal(1, 1, 0, 0, UNNAMED_WAIT, graph_still_s=0.1, settle_s=2.0) == ""
    # a twin found meanwhile is still refused for what it is
    assert "2 nodes of this name" in settle_refusal(2, 2, 0, 0, 5.0, graph_still_s=3.0,
                                                    settle_s=2.0)


def test_writers_without_a_node_name_hold_a_node_back_for_a_bounded_time():
    assert "node name" in settle_refusal(1, 1, 1, 0, 0.0)
    assert "node name" in settle_refusal(1, 1, 2, 0, UNNAMED_WAIT - 0.1)
    assert settle_refusal(1, 1, 1, 0, UNNAMED_WAIT) == ""            # not a ROS node


def test_a_planner_makes_its_command_writer_only_when_the_simulator_follows_none():
    """The simulator's /shaping/commander names the planner it follows: a newcomer that sees
    another one there (an older twin whose announcement is late, or a killed planner whose
    writer the graph still shows) makes no writer, so it is never a second commander."""
    assert commander_refusal("") == ""
    assert "follows /planner" in commander_refusal("/planner")
    assert "waiting for the simulator's commander" in commander_refusal(None)
    assert commander_refusal(None, expected=False) == ""      # check_cell off: not asked


def test_the_gate_lets_go_of_a_bound_planner_the_graph_no_longer_shows():
    from rheo_shaping.safety.command_gate import CommandGate, Publisher, ToolLimits
    gate = CommandGate(ToolLimits(max_speed=0.1, max_accel=1.0, max_jump=0.01))
    old, new = Publisher("/planner", "01.aa"), Publisher("/planner", "01.bb")
    assert gate.commander([]) == ""
    assert gate.source([old], 1) == "" and gate.commander([old]) == "/planner"
    assert gate.commander([old, new]) == "/planner"       # the old one is still there
    assert gate.commander([new]) == ""                    # gone: the tool is free to take
    assert gate.source([new], 1) == ""                     # the new writer's own count
    # the graph learns a writer's node name after the writer: the same GID is the same one
    gate = CommandGate(ToolLimits(max_speed=0.1, max_accel=1.0, max_jump=0.01))
    unnamed = Publisher("_NODE_NAMESPACE_UNKNOWN_/_NODE_NAME_UNKNOWN_", "01.aa")
    assert gate.source([unnamed], 1) == ""
    assert gate.commander([old]) == "/planner"            # named now, still bound
    assert gate.source([old], 2) == ""
