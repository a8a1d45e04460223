"""Freshness of a stream judged fairly on a busy machine (no ROS here).

A node's watchdog asks, on a timer of its own, how old the newest sample of a
stream is (a heartbeat, tension data, set-points).  On a loaded computer the
node's process may itself be descheduled for longer than the timeout; when it
runs again the sample it waits for may already sit, unread, in its queue
behind this very timer.  Declaring the stream dead then would be a verdict on
the node's own stall, not on the stream.  :class:`Freshness` therefore judges
a stream stale only when the previous check was recent (the node had the
chance to read what arrived): after a stall of its own the node gets one more
check, i.e. one more timer period, before it may call the stream stale, and
only when the stream was still fresh at the previous check.  A stream that
really stopped is still found stale one check later at most, also on a node
that stalls at every check.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field


@dataclass
class StallGuard:
    """Whether the checker itself stood still: more than ``limit`` [s] since its previous
    check (steady-clock nanoseconds [ns])."""

    limit: float
    _last: int | None = field(default=None, init=False)
    previous: int | None = field(default=None, init=False)   # the check before the last [ns]

    def check(self, now_ns: int) -> bool:
        """Record a check at ``now_ns``; True when the previous one was over ``limit`` ago."""
        now_ns = int(now_ns)
        stalled = self._last is not None and (now_ns - self._last) / 1e9 > self.limit
        self.previous, self._last = self._last, now_ns
        return stalled

    def excuses(self, stalled: bool, last_rx_ns: int | None, timeout: float) -> bool:
        """Whether a stall excuses a stream's age at this check: only when the stream was
        still fresh at the previous check (a sample that arrived before it has been read by
        now).  A node that stalls at every check therefore still finds a dead stream, one
        check after it went silent, instead of excusing it forever."""
        if not stalled or last_rx_ns is None or self.previous is None:
            return False
        return (self.previous - int(last_rx_ns)) / 1e9 <= timeout


@dataclass
class Freshness:
    """Age bookkeeping of one stream; times are steady-clock nanoseconds [ns].

    ``timeout`` [s]: the age beyond which the stream counts as lost.
    """

    timeout: float
    _last_rx: int | None = field(default=None, init=False)
    _guard: StallGuard = field(init=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.timeout) and self.timeout > 0.0):
            raise ValueError(
                f"timeout = {self.timeout!r} s is invalid: expected a finite value > 0")
        self._guard = StallGuard(0.5 * self.timeout)

    def received(self, now_ns: int) -> None:
        """A sample arrived at ``now_ns``."""
        self._last_rx = int(now_ns)

    @property
    def ever_received(self) -> bool:
        return self._last_rx is not None

    def age(self, now_ns: int) -> float:
        """Seconds [s] since the newest sample (inf before the first)."""
        return math.inf if self._last_rx is None else (int(now_ns) - self._last_rx) / 1e9

    def stale(self, now_ns: int) -> bool:
        """Whether the stream counts as lost at this check (call it from the watchdog).

        Lost: a sample is older than ``timeout`` and the previous check was at most
        ``timeout / 2`` ago.  Before the first sample the stream is lost."""
        stalled = self._guard.check(now_ns)
        if self._last_rx is None:
            return True
        return (self.age(now_ns) > self.timeout
                and not self._guard.excuses(stalled, self._last_rx, self.timeout))
