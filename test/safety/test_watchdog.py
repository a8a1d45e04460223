"""Freshness: a stream is stale after its timeout, except on the first check after the
checker's own stall, and a stopped stream is found at most one check later."""
from __future__ import annotations

import pytest

from rheo_shaping.safety.watchdog import Freshness

MS = 1_000_000


def test_regular_checks_find_a_stopped_stream_after_the_timeout():
    f = Freshness(timeout=0.3)
    assert f.stale(0) and not f.ever_received           # nothing yet: lost
    f.received(0)
    t = 0
    while not f.stale(t):
        t += 20 * MS                                     # a 20 ms watchdog
    assert 300 * MS < t <= 320 * MS                      # timeout < age <= timeout + period
    assert f.age(t) == pytest.approx(t / 1e9)


def test_a_stall_of_the_checker_gets_one_more_check_then_the_queued_sample_counts():
    f = Freshness(timeout=0.3)
    f.received(0)
    assert not f.stale(20 * MS)
    # the checker's process is descheduled for 0.8 s; the sample that arrived meanwhile
    # is still unread when the watchdog runs first
    assert not f.stale(820 * MS)                         # its own stall: one more check
    f.received(821 * MS)                                 # the queued sample is read
    assert not f.stale(840 * MS)


def test_a_stream_that_stopped_during_the_stall_is_stale_one_check_later():
    f = Freshness(timeout=0.3)
    f.received(0)
    assert not f.stale(20 * MS)
    assert not f.stale(820 * MS)                         # stall: grace
    assert f.stale(840 * MS)                             # nothing arrived: lost


def test_a_checker_stalled_at_every_check_still_finds_a_stopped_stream():
    """The stall excuses the stream only when it was fresh at the previous check: a node
    descheduled for 0.4 s before every check (timeout 0.3 s) finds a dead stream one
    check after it went silent, instead of excusing it forever."""
    f = Freshness(timeout=0.3)
    f.received(0)
    assert not f.stale(20 * MS)                          # a regular check
    assert not f.stale(420 * MS)                         # stalled; fresh at 20 ms: excused
    assert f.stale(820 * MS)                             # stalled; 0.42 s old at 420 ms: lost


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_timeouts_are_refused(bad):
    with pytest.raises(ValueError, match="timeout"):
        Freshness(timeout=bad)
