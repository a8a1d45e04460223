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
from typing import TYPE_CHECKING, Callable

import numpy as np

from ..units import NS
from .states import MOVING

if TYPE_CHECKING:
    from .stopping import TrajectoryStreamer

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


@dataclass(frozen=True, kw_only=True)
class StartFacts:
    """What the planner holds at a supervision tick before a run (the inputs that cost
    nothing to know; the others are asked of the node only when they matter)."""

    aborted: bool                  # an abort is latched
    autostart: bool                # the parameter
    start_requested: bool          # ~/start was called
    pose_known: bool               # a /tool/pose has arrived
    hold_known: bool               # where the tool holds is known (after a run)
    hold_ns: int | None            # the last run's newest set-point [ns]
    pose_ns: int | None            # the newest executed pose's stamp [ns]
    now_ns: int                    # the node's clock (0: no /clock yet)
    monitor_ok: bool               # the interlock


def start_inputs(f: StartFacts, pose_publishers: Callable[[], int],
                 tool_away: Callable[[], str], refusal: Callable[[], str],
                 lead: Callable[[int], str], subscribers: Callable[[], int]) -> StartInputs:
    """The :class:`StartInputs` of a tick: the graph queries and the node's checks asked
    only when a start is wanted and not latched off (else the planner idles or holds), the
    checks only behind the interlock, the lead only once the clock runs."""
    wants = f.autostart or f.start_requested
    active = wants and not f.aborted
    return StartInputs(
        aborted=f.aborted, wants_start=wants, start_requested=f.start_requested,
        pose_unknown=(active and not f.pose_known and not f.hold_known
                      and pose_publishers() > 0),
        tool_away=tool_away() if active else "", monitor_ok=f.monitor_ok,
        refusal=refusal() if active and f.monitor_ok else "",
        lead=lead(f.now_ns) if active and f.monitor_ok and f.now_ns > 0 else "",
        now_ns=f.now_ns, subscribers=subscribers() if active else 0,
        arriving=(active and f.hold_ns is not None
                  and (f.pose_ns is None or f.pose_ns < f.hold_ns)))


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


@dataclass(frozen=True, kw_only=True)
class Heartbeat:
    """What the planner knows of the monitor's ``/shaping/ready`` heartbeat (steady clock)."""

    required: bool                 # wait_for_monitor
    received_ns: int | None        # when the newest one arrived [ns] (None: never)
    now_ns: int                    # now [ns]
    timeout: float                 # monitor_timeout [s]
    ready: bool                    # what the newest one said


def interlock(h: Heartbeat, untrusted: Callable[[], str] = lambda: "") -> tuple[bool, str]:
    """(the monitor allows motion, why not): a fresh "ready" heartbeat of the one trusted
    writer, or no heartbeat required (safety principle 6).  ``untrusted()``: why the
    heartbeat's writer is not trusted ("" if it is; a graph query, asked last)."""
    if not h.required:
        return True, ""
    if h.received_ns is None:
        return False, "no ready heartbeat from the monitor yet"
    age = (h.now_ns - h.received_ns) / NS
    if age > h.timeout:
        return False, f"no ready heartbeat from the monitor for {age:.2f} s"
    if not h.ready:
        return False, "the monitor reports not ready"
    why = untrusted()
    if why:
        return False, why
    return True, ""


def start_reply(state: str | None, aborted: str | None, settled: bool) -> tuple[bool, str]:
    """The answer to ``~/start``: refused while a run exists (``state``, None without one)
    or an abort is latched (``aborted``: its reason, None without one); else the start is
    requested and waits for the interlock (and for the twin check while not ``settled``)."""
    if state is not None:
        return False, f"already started ({state}); ~/reset first"
    if aborted is not None:
        return False, f"aborted ({aborted}); ~/reset first"
    return True, ("start requested: waiting for the interlock"
                  + ("" if settled else
                     " (starting up: checking that no other planner runs)"))


def reset_refusal(state: str | None) -> str:
    """Why ``~/reset`` may not re-arm the planner ("" if it may): the tool moves."""
    return f"refused: the tool is moving ({state})" if state in MOVING else ""


def executed_ns(now_ns: int, last_ns: int | None, pose_ns: int | None,
                t0_ns: int | None) -> int:
    """The time of the executed tool pose during a run [ns]: the pose's stamp, never after
    the newest set-point ``last_ns`` (its time when no pose of the run has arrived; now
    before any set-point)."""
    last = last_ns if last_ns is not None else now_ns
    if pose_ns is None or t0_ns is None or pose_ns < t0_ns:
        return last
    return min(pose_ns, last)


def reported_state(streamer_state: str | None, aborted: bool, now_ns: int,
                   t0_ns: int | None, process_time: float) -> str | None:
    """The state the planner reports for its run (None: keep the one it has): ``done`` only
    once the process time is over too, ``holding`` after an abort without a run."""
    if streamer_state is None:
        return "holding" if aborted else None
    if streamer_state == "done":
        assert t0_ns is not None               # a streamer that ran has its grid
        return "done" if now_ns >= t0_ns + process_time * NS - 1 else "running"
    return "waiting" if streamer_state == "idle" else streamer_state


def start_lead(now_ns: int, pose_ns: int | None, max_lead: float) -> str:
    """Why a stream could not keep within ``max_lead`` [s] of the executed pose ("" if it
    can): no pose yet, or the simulator's clock runs further ahead of its pose."""
    if pose_ns is None:
        return ("no /tool/pose yet: the planner streams only against the executed pose "
                "(its stamp bounds the lead)")
    ahead = (now_ns - pose_ns) / NS
    if ahead > max_lead:
        return (f"/clock runs {ahead:.3f} s ahead of /tool/pose, beyond max_lead "
                f"{max_lead:g} s: the simulator's step (real_time_factor x "
                f"step_period) must stay below max_lead")
    return ""


def lead_wait(now_ns: int, limit_ns: int, pose_ns: int | None, max_lead: float) -> str:
    """Why set-points wait for the tool now ("" if they do not): the clock is past the
    lead limit of the executed pose."""
    if now_ns <= limit_ns:
        return ""
    return (f"set-points wait for the tool: /tool/pose at {(pose_ns or 0) / NS:.3f} s, clock "
            f"{now_ns / NS:.3f} s (max_lead {max_lead:g} s)")


def stop_run(streamer: TrajectoryStreamer | None, grid: SetpointGrid | None, reason: str,
             executed: int) -> tuple[list[int], str] | None:
    """Stop a run (running, done or retracting) on an abort, from the executed time
    ``executed`` [ns] on the plan's exact state there (safety principles 3 and 5): the
    set-point times to send (again) now, so the stream stays continuous in position,
    velocity and acceleration, and what to log; None when no run moves (the abort only
    latches)."""
    if streamer is None or streamer.state not in ("running", "done", "retracting"):
        return None
    was = streamer.state
    streamer.abort(executed / NS, reason)
    assert streamer.abort_time is not None            # abort() gives it
    t = int(round(streamer.abort_time * NS))
    sends = (grid.rewind(t) if grid is not None and grid.last_ns is not None
             and t < grid.last_ns else [])
    stop = streamer.stop_plan
    return sends, (f"stopping from {was} at {t / NS:.6f} s, at rest in "
                   f"{stop.duration if stop else 0.0:.6f} s"
                   + (", then retracting to home" if was != "retracting" else ", then holding"))


class RunLatch:
    """What the planner keeps between runs: an abort latched until ``~/reset``, a start
    asked for by ``~/start``, a start that failed (until ``~/reset``), and where the tool
    holds after a run (its position [m] and the last run's newest set-point [ns]): a later
    run starts with an approach from there."""

    def __init__(self) -> None:
        self.aborted = False
        self.abort_reason = ""
        self.start_requested = False
        self.start_failed = ""
        self.hold: np.ndarray | None = None
        self.hold_ns: int | None = None

    def abort(self, reason: str) -> bool:
        """Latch an abort; False when one is latched already (the first reason stays)."""
        if self.aborted:
            return False
        self.aborted, self.abort_reason = True, reason
        return True

    def request_start(self, tool_away: str, pose: np.ndarray | None) -> None:
        """``~/start`` was accepted: with the tool away from where the plan starts
        (``tool_away``, a reason) and its measured ``pose`` [m] known, the run approaches
        from there."""
        self.start_requested = True
        if tool_away and pose is not None:
            self.hold = np.array(pose, dtype=float)

    def start_from(self, pose: np.ndarray | None) -> np.ndarray | None:
        """Where a run starts its approach [m] (None: at the plan's start): after a run,
        from the measured pose (a simulator's reset moves the tool to the movement's start,
        a hold stops it where it was, not where the stop ended), else nowhere."""
        return pose if self.hold is not None and pose is not None else self.hold

    def rearm(self, streamer: TrajectoryStreamer | None, last_ns: int | None,
              now_ns: int) -> str:
        """``~/reset`` accepted (the tool at rest): the latches cleared, the hold taken
        where the run's stream stands (its newest set-point at ``last_ns``, or now); the
        reply's message."""
        if streamer is not None and streamer.plan is not None:
            self.hold = streamer.setpoint((last_ns or now_ns) / NS)[0]
            self.hold_ns = last_ns
        self.aborted, self.abort_reason = False, ""
        self.start_requested, self.start_failed = False, ""
        hold = self.hold
        return "re-armed" + (f"; the tool holds at ({hold[0]:.4f}, {hold[1]:.4f}) m"
                             if hold is not None else "")
