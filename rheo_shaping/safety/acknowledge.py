"""The monitor's acknowledgements: which tension sample a simulator may run past.

A simulator faster than real time waits, before each step, until the monitor has
acknowledged its newest tension samples (``monitor_lead``, docs/ros.md).  The
monitor acknowledges a sample once it has judged it, by the DDS sequence number of
the sample (``/sheet/tensions`` carries no stamp).  After an abort it withholds its
acknowledgements until the planner reports that it no longer runs the plan (its
state on ``/shaping/planner_state``), or for at most ``hold`` seconds: so the
simulated sheet stands still while the abort travels to the planner, as a real
sheet would move only for that wall time.  Times are steady-clock nanoseconds.
"""
from __future__ import annotations

from ..planning.states import BEFORE_RUN, MOVING
from ..units import NS
from .watchdog import Freshness

#: The planner state in which it streams its plan (any other: stopped, stopping or
#: not started).
RUNNING = "running"


class Acknowledgements:
    """What the monitor acknowledges on ``/shaping/checked`` (0: nothing yet)."""

    def __init__(self, hold: float):
        self.hold_ns = int(round(hold * NS))   # longest wait for the planner's reaction [ns]
        self.judged = 0          # sequence number of the newest judged sample
        self.acked = 0           # the newest acknowledged one
        self.planner_state = ""  # the planner's last reported state ("" unknown)
        self._held_since: int | None = None

    @property
    def holding(self) -> bool:
        """Whether acknowledgements are withheld (an abort not yet reacted to)."""
        return self._held_since is not None

    def on_judged(self, seq: int) -> int | None:
        """Sample ``seq`` was judged; the number to acknowledge now, or None."""
        if seq <= self.judged:
            return None
        self.judged = seq
        return self._release()

    def on_abort(self, steady_ns: int) -> None:
        """The monitor aborted: hold while the planner (if one is known) runs its plan."""
        if self.planner_state == RUNNING and self._held_since is None:
            self._held_since = steady_ns

    def on_planner_state(self, state: str) -> int | None:
        """The planner reported ``state``; the number to acknowledge now, or None.  A state
        before a run while the known planner moves the tool is another planner's (a twin
        that starts and yields): ignored, so it cannot lift the hold of an abort (seen in
        the attack campaign at x10: a twin's "starting" made the monitor believe no plan
        ran, the abort withheld nothing, and the sheet was stretched past F_break before
        the simulator held)."""
        if self.planner_state in MOVING and state in BEFORE_RUN:
            return None
        self.planner_state = state
        if state != RUNNING and self._held_since is not None:
            self._held_since = None
            return self._release()
        return None

    def tick(self, steady_ns: int) -> int:
        """The number to (re-)publish at a watchdog tick, after the hold's limit too."""
        if self._held_since is not None and steady_ns - self._held_since >= self.hold_ns:
            self._held_since = None
        self._release()
        return self.acked

    def reset(self) -> int | None:
        """The monitor was re-armed: no hold; the number to acknowledge now, or None."""
        self._held_since = None
        return self._release()

    def _release(self) -> int | None:
        if self._held_since is not None or self.judged <= self.acked:
            return None
        self.acked = self.judged
        return self.acked


class MonitorLead:
    """The simulator's side: whether its next step must wait for the monitor.

    ``lead``: the most unacknowledged tension samples it may have published (0: never
    wait); ``timeout`` [s]: acknowledgements older than this count as stopped, and the
    simulator no longer waits for them (a monitor that is gone, or a cell without one).
    Until the first acknowledgement arrives, it does not wait either.
    """

    def __init__(self, lead: int, timeout: float):
        self.lead = int(lead)
        self.sent = 0            # tension samples published (= their DDS sequence numbers)
        self.checked = 0         # the newest of them the monitor has acknowledged
        self.waits = 0           # steps held back so far
        self._timeout = timeout
        self._fresh: Freshness | None = None

    def published(self) -> None:
        """One more tension sample was published."""
        self.sent += 1

    def on_checked(self, seq: int, steady_ns: int) -> None:
        """An acknowledgement of sample ``seq`` arrived at ``steady_ns``."""
        self.checked = max(self.checked, int(seq))
        if self._fresh is None:
            self._fresh = Freshness(self._timeout)
        self._fresh.received(steady_ns)

    def lost(self, steady_ns: int) -> bool:
        """Whether acknowledgements came and then stopped for over ``timeout`` (a frozen or
        dead monitor)."""
        return self._fresh is not None and self._fresh.stale(steady_ns)

    def lost_reason(self, steady_ns: int, commanded: bool, topic: str) -> str:
        """Why the simulator must hold its tool for its monitor ("" none): acknowledgements
        on ``topic`` came and stopped for over the timeout while the tool is ``commanded``
        (a set-point came since the run began).  Before the first set-point a lapse holds
        nothing: the tool stands still and the planner does not start it without the
        monitor's heartbeat, and a latched hold would wedge a cell whose busy computer
        starved its monitor for half a second at start-up."""
        if not (commanded and self.lost(steady_ns)):
            return ""
        return f"monitor lost: no {topic} for over {self._timeout:g} s (monitor_timeout)"

    def behind(self, steady_ns: int) -> bool:
        """Whether a step must wait: ``lead`` published samples are unacknowledged while
        acknowledgements still arrive.  Counts the wait in :attr:`waits`."""
        wait = (self.lead > 0 and self._fresh is not None
                and self.sent - self.checked >= self.lead
                and not self._fresh.stale(steady_ns))
        self.waits += wait
        return wait

    def reset_refusal(self, steady_ns: int, foreign: str, topic: str) -> str:
        """Why a simulator's hold may not be reset now ("" if it may): the cause would
        latch it again at once: a second writer of the acknowledgements (``foreign``: its
        reason) or a lost monitor."""
        if foreign:
            return foreign
        if self.lost(steady_ns):
            return (f"the monitor is lost (no {topic} for over {self._timeout:g} s): "
                    f"restart it first")
        return ""

    def refusal(self, seq: int, untrusted: str) -> str:
        """Why acknowledgement ``seq`` is ignored ("" if it counts): its writer is not the
        bound monitor (``untrusted``: the reason), or it is beyond the samples published."""
        if untrusted:
            return untrusted
        if seq > self.sent:
            return f"beyond the {self.sent} samples published"
        return ""
