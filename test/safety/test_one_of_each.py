"""One of each (rheo_shaping.safety.one_of_each): who yields to whom, and how long a node
waits before it acts."""
from __future__ import annotations

import math

import pytest

from rheo_shaping.safety.one_of_each import (SETTLE_TIME, Announcement, settle_time,
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
