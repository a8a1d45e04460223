"""The planner's run decisions without ROS: when a plan may start, when a run must stop,
which set-points are due (the ``planner`` node's core, docs/safety.md).

:func:`start_decision` turns what the planner knows before a start (the interlock, the
tool's pose, the checks of cell, clocks and heartbeats, the lead, the clock, a matched
subscriber) into one state; :func:`running_decision` says why a running plan must stop;
:class:`SetpointGrid` gives the set-point times of a run on its control grid, never more
than ``max_lead`` ahead of the executed tool pose (:func:`lead_limit`), and starts again
from the executed time after a stop re-planned from there.  Times are integer
nanoseconds on the node's (or simulated) clock.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..units import NS

#: Most set-points in one batch (a clock that jumped far skips ahead).
MAX_BATCH = 5000


@dataclass(frozen=True)
class StartInputs:
    """What the planner knows at a supervision tick before its plan runs."""

    aborted: bool                  # an abort is latched (until ~/reset)
    wants_start: bool              # autostart, or ~/start was called
    start_requested: bool          # ~/start was called (the tool may be away: an approach)
    pose_unknown: bool             # no /tool/pose yet, no known hold, but a pose publisher
    tool_away: str                 # why autostart is unsafe ("" if it is not)
    monitor_ok: bool               # the interlock: a fresh ready heartbeat
    refusal: str                   # cell, clocks, heartbeats, twins ("" none)
    lead: str                      # why the stream could not keep within max_lead ("")
    now_ns: int                    # the node's clock (0: no /clock yet)
    subscribers: int               # matched subscribers of /tool/command
    arriving: bool = False         # after a run: the executed pose is stamped before the
    #                                last run's newest set-point (the tool still moves)


def start_decision(i: StartInputs) -> tuple[str, str]:
    """(state, reason) before the start: the state to report, ``"start"`` to start now.

    In order: nothing wanted (``idle``/``holding`` after an abort), the tool's pose
    unknown or still arriving at the last run's set-points, the tool away from home and
    start (autostart only), the interlock, the
    node's checks, the lead against the executed pose, the clock, a subscriber."""
    if i.aborted or not i.wants_start:
        return ("holding" if i.aborted else "idle"), ""
    if not i.start_requested and i.pose_unknown:
        return "waiting_for_pose", "know where the tool is before moving it"
    if i.arriving:
        # a later run starts from the measured pose: one the tool is still leaving would
        # make the approach's first set-point jump
        return "waiting_for_pose", ""
    if not i.start_requested and i.tool_away:
        return "tool_away", i.tool_away
    if not i.monitor_ok:
        return "waiting_for_monitor", ""
    if i.refusal:
        return ("waiting_for_cell" if "cell" in i.refusal else "waiting"), i.refusal
    if i.now_ns <= 0:
        return "waiting_for_clock", ""
    if i.lead:
        return "error", i.lead
    if i.subscribers == 0:
        # nobody would get the first set-points: a simulator or robot that matched later
        # would start mid-plan
        return "waiting_for_subscriber", ""
    return "start", ""


def running_decision(monitor_ok: bool, excused: bool, monitor_why: str,
                     refusal: str) -> str:
    """Why a running plan must stop ("" if it runs on): a lost monitor (unless this node's
    own stall excuses the heartbeat's age) or a failed check of cell, clocks, heartbeats."""
    if not monitor_ok and not excused:
        return f"planner: monitor lost ({monitor_why})"
    if refusal:
        return f"planner: {refusal}"
    return ""


def lead_limit(t0_ns: int, pose_ns: int | None, max_lead: float) -> int:
    """The newest set-point time allowed [ns]: the executed pose's stamp (not before the
    run's start) + ``max_lead`` [s]."""
    base = t0_ns if pose_ns is None else max(pose_ns, t0_ns)
    return base + int(round(max_lead * NS))


class SetpointGrid:
    """Set-point times of one run: t0 + k x period, then the clock's own time (simulated
    time), each once, none beyond a limit."""

    def __init__(self, t0_ns: int, period_ns: int):
        self.t0_ns, self.period_ns = int(t0_ns), int(period_ns)
        self.k = 0                       # next grid index
        self.last_ns: int | None = None  # newest time sent
        self.skipped = 0                 # grid points skipped after a far clock jump

    def due(self, now_ns: int, limit_ns: int, sim_time: bool) -> list[int]:
        """The times to send now, in order (and marked as sent): the grid up to
        ``min(now, limit)``, at most :data:`MAX_BATCH` of them, then ``now`` itself on
        simulated time (the set-point for the end of the simulator's step)."""
        out: list[int] = []
        n_due = (min(now_ns, limit_ns) - self.t0_ns) // self.period_ns - self.k + 1
        if n_due > MAX_BATCH:
            self.k += n_due - MAX_BATCH
            self.skipped += n_due - MAX_BATCH
        while True:
            t = self.t0_ns + self.k * self.period_ns
            if t > now_ns or t > limit_ns:
                break
            self._send(t, out)
            self.k += 1
        if sim_time and now_ns <= limit_ns:
            self._send(now_ns, out)
        return out

    def rewind(self, t_ns: int) -> list[int]:
        """Send again from ``t_ns`` on (a stop re-planned from the executed time): returns
        ``[t_ns]`` (send it now), the grid goes on after it."""
        if self.last_ns is not None and t_ns <= self.last_ns:
            self.last_ns = t_ns - 1
        self.k = max((t_ns - self.t0_ns) // self.period_ns + 1, 0)
        out: list[int] = []
        self._send(t_ns, out)
        return out

    def _send(self, t: int, out: list[int]) -> None:
        if self.last_ns is None or t > self.last_ns:
            out.append(t)
            self.last_ns = t
