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


def test_a_node_acts_only_settled_on_the_simulators_cell_and_one_clock():
    from rheo_shaping.safety.one_of_each import cell_refusal
    args = dict(check_cell=True, cell_topic="/shaping/cell")

    def ask(value):
        return lambda: value

    def never():
        raise AssertionError("asked before the questions ahead of it passed")
    why, fault = cell_refusal("monitor", False, mismatch=never, clocks=never, **args)
    assert why == "starting up: checking that no other monitor of this name runs" and not fault
    why, fault = cell_refusal("planner", True, mismatch=ask(None), clocks=never, **args)
    assert why.startswith("waiting for the simulator's cell on /shaping/cell") and not fault
    differs = "the cell differs from the simulator's: movement.speed = 0.005 vs 0.002"
    assert cell_refusal("planner", True, mismatch=ask(differs), clocks=never,
                        **args) == (differs, True)
    assert cell_refusal("planner", True, mismatch=ask(""), clocks=ask(""), **args) == ("", False)
    two = "2 publishers of /clock: /sim, /rogue"
    assert cell_refusal("monitor", True, mismatch=ask(""), clocks=ask(two), **args) == (two, True)
    # without check_cell no fingerprint is awaited; the clocks are still checked
    assert cell_refusal("planner", True, check_cell=False, mismatch=never, clocks=ask(""),
                        cell_topic="/shaping/cell") == ("", False)


def test_the_presence_watch_settles_after_discovery_and_a_still_graph_and_yields_once():
    """PresenceWatch: the settle time counts from discovery and grows with it; the graph
    must hold still; a younger twin's announcement is counted, an older one makes the node
    yield once, and never once it acts."""
    from rheo_shaping.safety.one_of_each import Announcement, PresenceWatch
    S = 10**9
    mine = Announcement(100, 7, "h", "/cell/planner")
    w = PresenceWatch(mine, now_ns=0)
    w.seen(frozenset({"/cell/planner"}), 0)
    w.seen(frozenset({"/cell/planner", "/cell/simulator"}), 3 * S)   # discovery took 3 s
    assert w.peer_s == 3.0
    w.discovered(3 * S)
    assert w.settle_s == 3.0 and not w.due(5 * S) and w.due(6 * S)
    # the graph changed 3 s before: still for the settle time, so it may act
    assert w.settle(6 * S, same_nodes=1, same_writers=1, unnamed_writers=0) == ""
    assert w.settled and not w.due(7 * S)
    # a second watch that hears of a younger twin first, then of an older one
    v = PresenceWatch(mine, now_ns=0)
    younger = Announcement(200, 8, "h", "/cell/planner")
    assert v.heard(younger, acting=False) == ("", False) and v.younger == {younger}
    older = Announcement(50, 9, "h", "/cell/planner")
    why, yields = v.heard(older, acting=False)
    assert yields and why.startswith("a second /cell/planner in this namespace")
    assert v.twin == why and not v.due(100 * S)
    assert v.heard(older, acting=False) == (why, False)              # once
    # a node that acts runs on
    u = PresenceWatch(mine, now_ns=0)
    assert u.heard(older, acting=True)[1] is False and u.twin == ""
    # two of its name in the graph, one announced younger: it may act; else it waits
    t = PresenceWatch(mine, now_ns=0)
    assert t.settle(2 * S, same_nodes=2, same_writers=2, unnamed_writers=0).startswith(
        "2 nodes of this name in the graph and 0 announced as younger")
    t.heard(younger, acting=False)
    assert t.settle(2 * S, same_nodes=2, same_writers=2, unnamed_writers=0) == ""
