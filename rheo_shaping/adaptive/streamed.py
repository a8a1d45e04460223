"""The closed loop of one streamed run (the ``planner`` node's ``adaptive``), without ROS:
which executed pose becomes a sample, when a refresh is submitted to the worker process,
and what becomes of its result at the next control tick.

The node hands in what it receives (the newest tool wrench and contact tension, each
executed pose with its stamp) and, at each control tick, the running stream; a finished
refresh is taken (:meth:`StreamedLoop.take`: the rest of the stream replaced at the join,
or the re-plan dropped with the reason) and the next one submitted when the shaper says
it is due.  Times: node-clock nanoseconds in, process-time seconds (since the run's
start ``t0_ns``) to the shaper.
"""
from __future__ import annotations

import time
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any, Callable

from ..planning.run_state import SetpointGrid
from ..planning.stopping import TrajectoryStreamer
from ..units import NS
from .observe import Sample
from .online import OnlineShaper, OnlineStep
from .worker import ShaperProcess


#: Wall time [s] the first refresh of a run is taken to need before one is measured: the
#: estimate and re-plan took 0.22 s median, 0.31 s max of CPU at load 9-10 on this project's
#: 2-core machine (docs/closed-loop.md, "The cost of a refresh"), with margin.
FIRST_REFRESH_S = 0.5

#: Wall time [s] a paced simulated cell's simulator waits for a set-point (its
#: ``command_timeout``) while the stream waits at a refresh's join: below the monitor's
#: wall-clock bound on a silent simulator (10 x max_data_age, 5 s by default).
PACED_COMMAND_TIMEOUT = 4.0

#: Wall time [s] a paced stream waits at a refresh's join at most, below the simulator's
#: wait (:data:`PACED_COMMAND_TIMEOUT`), so that it never runs out of set-points and steps
#: on without the stream: a refresh slower still (a loaded machine) is not waited for; the
#: stream goes on and its re-plan, joined where the stream has passed, is dropped, named.
PACE_WAIT_S = 2.5


def join_lead(span: float, pace: float, refresh_wall_s: float) -> float:
    """Process time [s] from the newest set-point sent to a re-plan's join: twice the larger
    of what the last refresh took (``span`` [s] of process time streamed meanwhile) and what
    the next one will take at the cell's ``pace`` (process s per wall s, e.g. 10 at x10)
    in ``refresh_wall_s`` [s] of wall time.  A cell faster than real time streams seconds of
    process time during one refresh: a join of 1 s (the first refresh's, without this) had
    passed by the time its re-plan came, and the stroke ran on unchanged."""
    return 2.0 * max(span, pace * refresh_wall_s)


@dataclass(frozen=True, kw_only=True)
class Refresh:
    """A refresh taken at a control tick: its result, whether the stream switched to its
    re-plan, and the record published (``/shaping/estimate``)."""

    step: OnlineStep
    switched: bool
    note: str                       # "re-planned from t = ... s: " or "re-plan dropped (...): "
    data: dict[str, Any]

    @property
    def warning(self) -> bool:
        """A re-plan that could not be taken."""
        return self.step.plan is not None and not self.switched

    def status(self) -> tuple[str, str, dict[str, Any]]:
        """The closed loop's ``/diagnostics`` status after this refresh: (level, message,
        values).  WARN when the estimate cannot be used (the running plan goes on, the
        reason named), when no plan meets both limits (the one that keeps the sheet whole
        runs) or a re-plan was dropped; else OK."""
        e, step = self.step.estimate, self.step
        replan = step.replan.status.value if step.replan is not None else "none"
        bad = (not e.status.usable or replan in ("infeasible", "no_estimate")
               or self.warning)
        values = {"t [s]": step.t, "reason": step.reason.value, "estimate": e.status.value,
                  "k1 [N/m]": e.k1, "c2 [N s/m]": e.c2,
                  "mass per length [kg/m]": e.mass_per_length,
                  "k1 sigma [rel]": float(e.sigma_rel[0]),
                  "c2 sigma [rel]": float(e.sigma_rel[1]),
                  "mass sigma [rel]": float(e.sigma_rel[2]), "replan": replan,
                  "switched": self.switched, "cycle time [s]": step.schedule.cycle_time,
                  "worker CPU [s]": self.data.get("worker_cpu_s", 0.0)}
        return ("WARN" if bad else "OK"), f"{self.note}{step.message}", values


class StreamedLoop:
    """The closed loop of the run that started at ``t0_ns`` (``online``: its shaper,
    ``process``: the worker that refreshes it)."""

    def __init__(self, online: OnlineShaper, process: ShaperProcess,
                 monotonic: Callable[[], float] = time.monotonic, paced: bool = False):
        """``monotonic``: a wall clock [s] (the cell's pace and each refresh's wall time).

        ``paced``: the stream waits for its loop (a simulated cell, whose simulator steps
        only on set-points it has): while a refresh runs, no set-point is sent beyond its
        join (:meth:`limit_ns`), so every re-plan joins at ``join_lead`` of the shaper's
        config after what was streamed, whatever the refresh's wall time at the cell's
        pace.  Unpaced (a real cell, which cannot wait), the join is put beyond what the
        stream will send meanwhile (:func:`join_lead`)."""
        self.online, self.process, self.paced = online, process, paced
        self.cap_ns: int | None = None        # paced: the running refresh's join [ns]
        self.samples: list[Sample] = []       # taken since the last refresh was submitted
        self.work: Future | None = None       # the refresh running in the worker
        self.span = 0.0                       # s of process time the last refresh took
        self.began = 0.0                      # s, the stream's time when it was submitted
        self._clock = monotonic
        self._start: tuple[float, float] | None = None   # (wall s, streamed s) at 1st tick
        self._submitted = 0.0                 # wall s the running refresh was submitted
        self.refresh_wall_s = FIRST_REFRESH_S   # wall s the last refresh took

    def pose(self, xz, stamp_ns: int, t0_ns: int | None,
             wrench: tuple[float, float] | None, contact: float | None) -> None:
        """An executed tool pose [m] stamped ``stamp_ns``: a sample when the shaper wants
        one (a wrench is known, the run has started, later than the last sample)."""
        if t0_ns is None or wrench is None:
            return
        t = (stamp_ns - t0_ns) / NS
        if t >= 0.0 and self.online.wants(t) and (not self.samples
                                                  or t > self.samples[-1].t):
            sample = Sample(t=t, tool=(float(xz[0]), float(xz[1])), wrench=wrench,
                            contact_tension=contact)
            self.online.add(sample)
            self.samples.append(sample)

    def tick(self, st: TrajectoryStreamer, grid: SetpointGrid, pose_ns: int | None,
             pose) -> Refresh | None:
        """At a control tick: a finished refresh taken (returned), then the next one
        submitted when it is due (``pose``: the executed tool pose [m] at ``pose_ns``).
        A refresh that failed in the worker raises its error (the loop ends there)."""
        t0, taken = grid.t0_ns, None
        if self._start is None and grid.last_ns is not None:      # the stream's first tick
            self._start = (self._clock(), (grid.last_ns - t0) / NS)
        if self.work is not None and self.work.done():
            work, self.work, self.cap_ns = self.work, None, None
            last = grid.last_ns
            assert last is not None             # a refresh begins after a set-point is sent
            self.span = (last - t0) / NS - self.began
            self.refresh_wall_s = self._clock() - self._submitted
            index, step, cpu = work.result()
            self.process.cpu_s += cpu
            taken = self.take(index, step, st)
        last = grid.last_ns
        if (self.work is not None or st.state != "running" or pose_ns is None
                or pose is None or last is None or pose_ns < t0):
            return taken
        t = (pose_ns - t0) / NS
        reason = self.online.due(t)
        if reason is None:
            return taken
        samples, self.samples = self.samples, []
        streamed = self.began = (last - t0) / NS
        now = self._clock()
        assert self._start is not None          # set at the first tick with a set-point
        wall = now - self._start[0]
        pace = (streamed - self._start[1]) / wall if wall > 0.0 else 0.0
        self._submitted = now
        # paced: the shaper's own join_lead (its config), the stream held at the join
        lead = 0.0 if self.paced else join_lead(self.span, pace, self.refresh_wall_s)
        self.work = self.process.submit(samples, t, reason, (float(pose[0]), float(pose[1])),
                                        streamed, lead)
        if self.paced:                          # the join's time itself is not sent
            self.cap_ns = t0 + round((max(t, streamed) + self.online.config.join_lead)
                                     * NS) - 1
        return taken

    def serve_now(self) -> bool:
        """A paced stream waiting at its join is to be served now, on the node's wall-clock
        tick (its control timer runs on the cell's clock, which stands still while the
        simulator waits for the stream): the refresh has finished (:meth:`tick` takes it),
        or the wait ran out (:data:`PACE_WAIT_S`: the stream goes on without it)."""
        return self.cap_ns is not None and self.work is not None and (
            self.work.done() or self._waited_out())

    def limit_ns(self, state: str) -> int | None:
        """The newest set-point time [ns] the stream in ``state`` may send now: a paced
        loop's running refresh's join while the stream runs and the wait has not run out
        (:data:`PACE_WAIT_S`); None: no limit (a stop or a retract never waits)."""
        if state != "running" or self._waited_out():
            return None
        return self.cap_ns

    def _waited_out(self) -> bool:
        """The running refresh was submitted over :data:`PACE_WAIT_S` of wall time ago."""
        return self._clock() - self._submitted > PACE_WAIT_S

    def take(self, index: int, step: OnlineStep, st: TrajectoryStreamer) -> Refresh:
        """Refresh ``index``'s result: the running stream switches to its re-plan at the
        join (:meth:`~TrajectoryStreamer.replace_rest`, which refuses a join already streamed
        or a stream that stopped), and the shaper accepts it."""
        note = ""
        if step.plan is not None:
            try:
                st.replace_rest(step.plan, step.t_join)
                self.process.accept(index, step)
                note = f"re-planned from t = {step.t_join:.2f} s: "
            except (RuntimeError, ValueError) as exc:
                note = f"re-plan dropped ({exc}): "
        switched = note.startswith("re-planned")
        data = dict(step.as_dict(), switched=switched, worker_cpu_s=self.process.cpu_s,
                    refresh_wall_s=self.refresh_wall_s)
        return Refresh(step=step, switched=switched, note=note, data=data)
