"""What a node accepts of /clock (rheo_shaping.safety.clock_guard.ClockGuard), without ROS."""
from __future__ import annotations

import pytest

from rheo_shaping.safety.clock_guard import ClockGuard
from rheo_shaping.units import NS


def test_steps_within_the_bound_and_repeats_are_accepted():
    g = ClockGuard(max_jump=2.0)
    for t in (0, 1 * NS, 1 * NS, 3 * NS):            # a repeat (the held start) is fine
        assert g.check(t) == ""
    assert g.last_ns == 3 * NS and g.refused == 0


def test_a_forward_jump_beyond_the_bound_is_refused_and_not_applied():
    g = ClockGuard(max_jump=2.0)
    assert g.check(5 * NS) == ""
    why = g.check(35 * NS)                              # the forged +30 s message
    assert "jumped forward by 30.000000 s" in why and "max_clock_jump 2 s" in why
    assert g.last_ns == 5 * NS and g.refused == 1
    assert g.check(5 * NS + 2 * NS) == ""               # exactly the bound: accepted


def test_negative_and_backward_times_are_refused():
    g = ClockGuard(max_jump=2.0)
    assert "negative" in g.check(-1 * NS)
    assert g.last_ns is None
    assert g.check(10 * NS) == ""
    assert "ran backward from 10.000000 s to 9.000000 s" in g.check(9 * NS)
    assert g.last_ns == 10 * NS and g.refused == 2


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan")])
def test_the_bound_must_be_positive(bad):
    with pytest.raises(ValueError, match="max_jump must be > 0 s"):
        ClockGuard(bad)
