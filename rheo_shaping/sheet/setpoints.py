"""A run of the sheet under a stream of stamped tool set-points (the simulator node's core).

:class:`SetpointRun` holds what the ``simulator`` node decides without ROS: the set-point
buffer (newest wins for a time already commanded), the tool's position between stamps
(linear, then hold), whether a step lacks its set-point (lockstep), the start of the
process at the first set-point, the advance of the :class:`~.simulation.Simulation` to
the process end and beyond, and the peak tension of the process.  Times on the node's
(or simulated) clock are integer nanoseconds; process time is in seconds from the start.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from ..params.cell import CellParams
from ..units import NS
from .metrics import PeakTension, RunSummary
from .chain import ConvergenceError
from .simulation import Simulation

#: at most this many (process time, largest tension) pairs are kept in ``history``
HISTORY_LIMIT = 1_000_000


class SetpointRun:
    """The settled sheet at process time 0, stepped under buffered set-points."""

    def __init__(self, cell: CellParams, tool_start):
        self.cell = cell
        self._own_end = float(cell.movement.process_time)    # the params file's [s]
        self.sim = Simulation(cell, tool_start=tool_start)
        self.cmds: list[tuple[int, float, float]] = []   # (stamp [ns], x [m], z [m])
        self.offset_ns: int | None = None  # process time 0 on the node clock, once started
        self.broken = ""                   # the solver's failure, if any
        self.peak = PeakTension(-math.inf, 0, 0.0)
        #: (process time [s], largest link tension [N]) of every step
        self.history: list[tuple[float, float]] = []
        self.summary: RunSummary | None = None

    @property
    def started(self) -> bool:
        return self.offset_ns is not None

    @property
    def process_time(self) -> float:
        """s since the process started."""
        return float(self.sim.state.t)

    # -- set-points -------------------------------------------------------------------
    def command(self, t_ns: int, x: float, z: float) -> bool:
        """Buffer the set-point (x, z) [m] for time ``t_ns``; True if it started the process.

        A set-point for a time already commanded replaces what followed (newest wins).
        Process time 0 is the first set-point's time: the settled sheet waited at t = 0
        with the tool moved there, and the next step catches up through the buffer.
        """
        if self.cmds and t_ns <= self.cmds[-1][0]:
            self.cmds = [c for c in self.cmds if c[0] < t_ns]
        self.cmds.append((t_ns, x, z))
        if self.started:
            return False
        self.offset_ns = t_ns
        self.sim.tool_start = np.array([x, z])
        self.sim.reset()                           # the process starts with the tool here
        self.track(self.sim.state)                 # t = 0 counts, as offline
        return True

    def hold(self, t_ns: int) -> np.ndarray:
        """The tool holds where it is from ``t_ns`` on: every buffered set-point is dropped
        for one at the tool's present position; that position [m]."""
        tool = self.sim.state.tool
        self.cmds = [(int(t_ns), float(tool[0]), float(tool[1]))]
        return tool.copy()

    def start_at(self, t_ns: int) -> None:
        """Start the process at ``t_ns`` without a set-point (the tool stays at its start)."""
        self.offset_ns = t_ns
        self.track(self.sim.state)

    def tool_at(self, t_ns: float) -> np.ndarray:
        """Set-point at node time ``t_ns``: linear between stamps, then hold."""
        cmds = self.cmds
        if not cmds:
            return self.sim.state.tool.copy()
        if t_ns >= cmds[-1][0]:
            return np.array(cmds[-1][1:])
        if t_ns <= cmds[0][0]:
            return np.array(cmds[0][1:])
        ts = np.fromiter((c[0] for c in cmds), dtype=np.int64, count=len(cmds))
        k = int(np.searchsorted(ts, t_ns, side="right"))
        (t0, x0, z0), (t1, x1, z1) = cmds[k - 1], cmds[k]
        s = (t_ns - t0) / (t1 - t0)
        return np.array([x0 + s * (x1 - x0), z0 + s * (z1 - z0)])

    def lacks_setpoint(self, target_ns: int) -> bool:
        """The step to ``target_ns`` would outrun the newest set-point (lockstep waits)."""
        return self.started and bool(self.cmds) and self.cmds[-1][0] < target_ns

    def prune(self, keep_from_ns: int) -> None:
        """Drop the set-points no step after ``keep_from_ns`` needs."""
        ts = [c[0] for c in self.cmds]
        k = max(int(np.searchsorted(ts, keep_from_ns, side="right")) - 1, 0)
        if k > 0:
            del self.cmds[:k]

    # -- stepping ---------------------------------------------------------------------
    def process_time_at(self, t_ns: int) -> float:
        """Process time [s] of node time ``t_ns`` (the run must have started)."""
        if self.offset_ns is None:
            raise RuntimeError("process_time_at() before the run started (no time offset)")
        return (t_ns - self.offset_ns) / NS

    def advance(self, target_ns: int) -> float | None:
        """Step the sheet towards node time ``target_ns`` (once started, until it fails).

        A step that would cross ``movement.process_time`` stops there: :attr:`summary` is
        set and the process time is returned (the caller may publish that state, then
        calls again to go on); otherwise None.  A solver failure sets :attr:`broken`.
        """
        if not self.started or self.broken:
            return None
        offset = self.offset_ns
        tool_at = lambda p: self.tool_at(offset + p * NS)   # noqa: E731
        p_end = self.process_time_at(target_ns)
        pt = self.cell.movement.process_time
        try:
            if self.summary is None and self.sim.state.t < pt <= p_end + 1e-9:
                self.sim.advance_to(pt, tool_at(pt), on_step=self.track, tool_at=tool_at)
                self.summary = RunSummary.of(self.cell.material.F_break, self.peak,
                                             self.sim.delta())
                return pt
            if p_end > self.sim.state.t:
                self.sim.advance_to(p_end, tool_at(p_end), on_step=self.track, tool_at=tool_at)
        except (ConvergenceError, FloatingPointError, ValueError) as exc:
            self.broken = f"{type(exc).__name__}: {exc}"
        return None

    def step_to(self, target_ns: int,
                start_on_command: bool) -> tuple[float | None, int | None]:
        """One step of the simulator to node time ``target_ns``: the process starts with it
        unless it waits for a set-point (``start_on_command``), then the sheet advances
        (:meth:`advance`).  Returns (the process end [s] if this step reached it, the node
        time [ns] of that end when it lies before the target: the state there is the one to
        publish, then :meth:`advance` goes on to the target)."""
        if not self.started and not start_on_command:
            self.start_at(target_ns)
        finished = self.advance(target_ns)
        if finished is None or finished >= self.process_time_at(target_ns) - 1e-9:
            return finished, None
        offset = self.offset_ns
        assert offset is not None                 # a run that advanced has started
        return finished, offset + int(round(finished * NS))

    def track(self, state) -> None:
        """Note a step's largest link tension; the peak counts up to the process end."""
        i = int(np.argmax(state.tension))
        value = float(state.tension[i])
        if len(self.history) < HISTORY_LIMIT:
            self.history.append((float(state.t), value))
        if state.t <= self.cell.movement.process_time + 1e-9 and value > self.peak.value:
            self.peak = PeakTension(value, i + 1, float(state.t))

    def end_at(self, process_time: float) -> None:
        """The process ends at ``process_time`` [s] (the cycle of a re-planned movement: its
        gap judged at its own end, its peak counted to there), never before the cell's own
        process time; a time already passed, or a process already ended, changes nothing."""
        end = max(float(process_time), self._own_end)
        if (self.summary is None and process_time > self.sim.state.t
                and end != self.cell.movement.process_time):     # called at every spin
            self.cell = replace(self.cell, movement=replace(self.cell.movement,
                                                            process_time=end))

    def summary_so_far(self) -> RunSummary:
        """:attr:`summary` once the process has ended, else the figures up to now."""
        if self.summary is not None:
            return self.summary
        return RunSummary.of(self.cell.material.F_break, self.peak, self.sim.delta())

    def tensions(self) -> np.ndarray:
        """The link tensions [N] to publish: NaN once the solver has failed."""
        st = self.sim.state
        return np.full_like(st.tension, np.nan) if self.broken else st.tension


# ------------------------------------------------------------------ the simulator's policy
#: What a simulator on simulated time does at a tick (:func:`next_step`).
HOLD_FOR_START = "hold_for_start"    # /clock stays; the state is re-published for late joiners
WAIT_MONITOR = "wait_monitor"        # the monitor lags by monitor_lead samples: retried later
WAIT_SETPOINT = "wait_setpoint"      # lockstep: the step's set-point has not come yet
LATE_STEP = "late_step"              # the step goes on without its set-point (the tool holds)
STEP = "step"


def next_step(lockstep: bool, start_on_command: bool, started: bool, clock_started: bool,
              monitor_behind: Callable[[], bool], lacks_setpoint: Callable[[], bool],
              held: bool, stream_live: Callable[[], bool]) -> str:
    """The simulator's step policy on simulated time, one of the names above, in order:

    * before the first set-point, with lockstep and ``start_on_command``, once the clock
      has made its first step, /clock holds (the plan starts where the simulation is, however
      late its first set-points come);
    * the monitor is ``monitor_lead`` samples behind: wait (safety.acknowledge.MonitorLead);
    * the step lacks its set-point and the tool is not held: wait for it while lockstep
      and set-points still stream (``command_timeout``), else step without it;
    * else step.

    The callables are asked only when the policy gets to them (the monitor's count of
    waits is one of them)."""
    if lockstep and start_on_command and not started and clock_started:
        return HOLD_FOR_START
    if monitor_behind():
        return WAIT_MONITOR
    if lacks_setpoint() and not held:
        return WAIT_SETPOINT if lockstep and stream_live() else LATE_STEP
    return STEP


#: Wall-clock time [s] between re-publications of the unchanged state while /clock holds
#: for the first set-point (the monitor's data stay fresh; nothing else changes).
HOLD_REPUBLISH = 0.1


@dataclass(frozen=True, kw_only=True)
class Tick:
    """What a simulator on simulated time does at a tick (:meth:`SimClock.tick`)."""

    step_to: int | None = None     # node time [ns] to step to (None: no step now)
    clock_ns: int | None = None    # /clock to publish first [ns] (None: none)
    wait: bool = False             # the step waits: retried at the next acknowledgement or
    #                                set-point (the step stays due)
    republish: bool = False        # held for the start: the same state again, fresh for the
    #                                monitor
    late: bool = False             # the step goes on without its set-point


class SimClock:
    """A simulator's simulated time: the newest computed state's time ``t_ns`` and the step
    ``dt_ns`` [ns], with the counts of its policy's choices (:func:`next_step`)."""

    def __init__(self, dt_ns: int):
        self.dt_ns = max(int(dt_ns), 1)
        self.t_ns = 0                    # time of the newest computed state [ns]
        self.clock_holds = 0             # ticks held at the start for the first set-point
        self.waits = 0                   # lockstep waits for a set-point
        self.late_steps = 0              # steps taken without their set-point
        self._republished: int | None = None   # steady time of the last re-publication [ns]

    def tick(self, choice: str, steady_ns: int) -> Tick:
        """The tick for the policy's ``choice`` at steady time ``steady_ns`` [ns]: /clock one
        step ahead of a step, or held at the next step's time (then the state is published
        again every :data:`HOLD_REPUBLISH` s)."""
        target = self.t_ns + self.dt_ns
        if choice == HOLD_FOR_START:
            self.clock_holds += 1
            again = (self._republished is None
                     or steady_ns - self._republished >= HOLD_REPUBLISH * NS)
            if again:
                self._republished = steady_ns
            return Tick(clock_ns=target, republish=again)
        if choice in (WAIT_MONITOR, WAIT_SETPOINT):
            self.waits += choice == WAIT_SETPOINT
            return Tick(wait=True)
        self.late_steps += choice == LATE_STEP
        return Tick(step_to=target, clock_ns=target + self.dt_ns, late=choice == LATE_STEP)


def run_status(broken: str, held: str, started: bool, done: bool, t: float,
               process_time: float) -> tuple[str, str]:
    """The simulator's /diagnostics level and message: (level, message)."""
    if broken:
        return "ERROR", f"sheet solver failed: {broken}"
    if held:
        return "ERROR", f"the tool holds: {held}"
    if not started:
        return "OK", "waiting for the first /tool/command"
    if not done:
        return "OK", f"process time {t:.1f} s"
    return "OK", f"process done at {process_time:g} s"
