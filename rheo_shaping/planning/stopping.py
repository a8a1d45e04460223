"""Planned, jerk-limited stops (IEC 60204-1 category 2) and the online streamer.

Safety principles 3-5 (docs/safety-principles.md): an abort latches, the stop is planned (ruckig
from
the current state to rest within the limits, then hold), and the monitor
budgets its threshold with the stopping time.  No ROS imports here.

* :func:`stop_from_state`: a ruckig stop (``ControlInterface.Velocity``,
  target velocity and acceleration 0) from any, possibly accelerating, state.
* :func:`stopping_time` / :func:`stopping_distance`: closed forms for a stop
  from constant speed.
* :class:`TrajectoryStreamer`: the set-point source the planner node calls at
  its control rate (run a plan, abort, stop, slow retract, hold).
"""
from __future__ import annotations

import math
from typing import Optional, Sequence

import numpy as np
from ruckig import ControlInterface, InputParameter, Synchronization

from ..params.validators import (PointLike, check_finite, check_non_negative, check_point,
                                 check_positive)
from .pieces import AxisBuilder, append_trajectory, as_point, axis_scale, calculate
from .plans import (DEFAULT_RETRACT_LIMITS, MotionLimits, Plan, Segment, Waypoint,
                    assemble_plan, plan_waypoints)
from .states import MOVING, STREAM_STATES

__all__ = ["stop_from_state", "stopping_time", "stopping_distance", "TrajectoryStreamer", "STATES"]

#: Relative tolerance under which velocity and acceleration count as collinear.
COLLINEAR_RTOL = 1e-9


def stopping_time(speed: float, limits: MotionLimits) -> float:
    """Time [s] of the time-optimal jerk-limited stop from constant ``speed`` [m/s].

    ``v/a + a/j`` if ``v >= a^2/j`` (the deceleration reaches ``a_max``),
    else ``2*sqrt(v/j)``.
    """
    v = check_non_negative("speed [m/s]", speed)
    a, j = limits.a_max, limits.j_max
    return v / a + a / j if v >= a * a / j else 2.0 * math.sqrt(v / j)


def stopping_distance(speed: float, limits: MotionLimits) -> float:
    """Distance [m] travelled during :func:`stopping_time` (the velocity ramp
    is point-symmetric, so it is ``speed * T / 2``)."""
    return 0.5 * check_non_negative("speed [m/s]", speed) * stopping_time(speed, limits)


def stop_from_state(position: PointLike, velocity: PointLike, acceleration: PointLike,
                    limits: MotionLimits) -> Plan:
    """Jerk-limited stop to rest from ``position`` [m], ``velocity`` [m/s],
    ``acceleration`` [m/s^2] (each (x, z)), within ``limits`` (norms).

    When velocity and acceleration are collinear (always so on a straight
    plan) the stop stays on that line, phase-synchronised with per-axis limits
    scaled by the direction cosines, and is time-optimal for the path limits.
    Otherwise each axis gets ``limit/sqrt(2)`` so the norms still hold.  An
    acceleration above ``a_max`` is first brought back by ruckig's brake
    pre-profile at full jerk.  The returned plan has one ``"move"`` segment
    labelled ``"stop"`` (none when already at rest).
    """
    p = check_point("position [m]", position)
    v = check_point("velocity [m/s]", velocity)
    a = check_point("acceleration [m/s^2]", acceleration)
    axes = (AxisBuilder(p[0]), AxisBuilder(p[1]))
    if not v.any() and not a.any():
        return assemble_plan([], 0.0, limits, p, axes)
    inp = InputParameter(2)
    inp.control_interface = ControlInterface.Velocity
    inp.current_position = p.tolist()
    inp.current_velocity = v.tolist()
    inp.current_acceleration = a.tolist()
    inp.target_velocity = [0.0, 0.0]
    inp.target_acceleration = [0.0, 0.0]
    u = v / np.linalg.norm(v) if v.any() else a / np.linalg.norm(a)
    if abs(u[0] * a[1] - u[1] * a[0]) <= COLLINEAR_RTOL * np.linalg.norm(a):
        c = axis_scale(u)
        inp.synchronization = Synchronization.Phase
    else:
        c = np.full(2, math.sqrt(0.5))
        inp.synchronization = Synchronization.Time
    inp.max_velocity = (limits.v_max * c).tolist()  # unused by the velocity interface
    inp.max_acceleration = (limits.a_max * c).tolist()
    inp.max_jerk = (limits.j_max * c).tolist()
    traj = calculate(inp)
    end = append_trajectory(axes, traj, 0.0)
    seg = Segment(0.0, traj.duration, "move", as_point(p), as_point(end), "stop")
    return assemble_plan([seg], traj.duration, limits, p, axes)


#: States of :class:`TrajectoryStreamer` (:mod:`rheo_shaping.planning.states`).
STATES = STREAM_STATES


class TrajectoryStreamer:
    """Online set-point source for the planner node (times [s] on its clock).

    ``idle`` --start--> ``running`` --(plan over)--> ``done``.  ``abort(t)``
    from ``running``/``done`` switches at once to a ruckig stop from the exact
    current state (``stopping``), then, if ``home_xz`` is set, a slow retract
    through ``retract_via`` to ``home_xz`` within ``retract_limits``
    (``retracting``), then ``holding``.  An abort while retracting stops and
    holds where the tool comes to rest.  The abort latches: the old plan is
    never resumed; :meth:`reset` then :meth:`start` begin a new run.

    Times passed to :meth:`setpoint` are made monotone (an earlier time is
    treated as the latest one seen), so the set-point never runs backwards.
    """

    # the run's state, set by _clear() (the plans and times are None until they exist)
    _state: str
    _final_state: str
    _main: Optional[Plan]
    _stop: Optional[Plan]
    _phase_plan: Optional[Plan]
    _phase_t0: float
    _queue: list[tuple[str, Plan]]
    _t_last: float
    _abort_time: Optional[float]
    _abort_reason: str
    _rest_time: Optional[float]

    def __init__(self, home_xz: Optional[PointLike] = None,
                 retract_limits: MotionLimits = DEFAULT_RETRACT_LIMITS, *,
                 retract_via: Sequence[Waypoint] = (),
                 initial_xz: Optional[PointLike] = None,
                 jump_tolerance_m: float = 1e-6) -> None:
        self.home = None if home_xz is None else check_point("home_xz [m]", home_xz)
        self.retract_limits = retract_limits
        self.retract_via = tuple(retract_via)
        check_positive("jump_tolerance_m [m]", jump_tolerance_m)
        self.jump_tolerance_m = float(jump_tolerance_m)
        hold = initial_xz if initial_xz is not None else home_xz
        self._hold: Optional[np.ndarray] = None if hold is None else check_point(
            "initial_xz [m]", hold)
        self._known_hold = initial_xz is not None
        self._clear()

    # -- queries --------------------------------------------------------------
    @property
    def state(self) -> str:
        """One of :data:`STATES` as of the latest :meth:`setpoint` / :meth:`abort`."""
        return self._state

    @property
    def aborted(self) -> bool:
        """True from an abort until :meth:`reset`."""
        return self._abort_time is not None

    @property
    def abort_time(self) -> Optional[float]:
        """When the abort took effect [s], or None."""
        return self._abort_time

    @property
    def abort_reason(self) -> str:
        """The reason given to :meth:`abort`."""
        return self._abort_reason

    @property
    def rest_time(self) -> Optional[float]:
        """When the abort's stop reaches rest [s] (abort time + stop duration), or None."""
        return self._rest_time

    @property
    def plan(self) -> Optional[Plan]:
        """The plan given to :meth:`start` (None when idle)."""
        return self._main

    @property
    def stop_plan(self) -> Optional[Plan]:
        """The stop computed by :meth:`abort` (None before an abort)."""
        return self._stop

    # -- commands -------------------------------------------------------------
    def start(self, plan: Plan, t0: float) -> None:
        """Run ``plan`` from time ``t0`` [s].  Only from ``idle``; the plan must
        start where the tool holds (within ``jump_tolerance_m``) if that is known."""
        if self._state != "idle":
            raise RuntimeError(
                f"start() needs state 'idle', not {self._state!r} (call reset() first)")
        if not isinstance(plan, Plan):
            raise TypeError(f"plan must be a Plan, got {type(plan).__name__}")
        t0 = check_finite("t0 [s]", t0)
        if self._hold is not None and self._known_hold:
            jump = float(np.linalg.norm(np.asarray(plan.start) - self._hold))
            if jump > self.jump_tolerance_m:
                raise ValueError(
                    f"plan starts {jump:.3g} m from the held position {self._hold.tolist()}: "
                    f"expected <= jump_tolerance_m = {self.jump_tolerance_m:g} m")
        self._main = plan
        self._phase_plan, self._phase_t0, self._queue = plan, t0, []
        self._state, self._final_state = "running", "done"

    def replace_rest(self, plan: Plan, t_join: float) -> None:
        """Follow ``plan`` instead of the running plan from ``t_join`` [s, plan time, the same
        origin as the running plan's] on: only while ``running``, before any time at or after
        ``t_join`` was sampled, and with ``plan`` in the running plan's exact state there
        (position, velocity, acceleration within 1e-9): the stream stays continuous.  A
        RuntimeError or ValueError says which condition failed; nothing changes then."""
        if self._state != "running" or self._main is None or self._phase_plan is not self._main:
            raise RuntimeError(f"replace_rest() needs state 'running', not {self._state!r}")
        if not isinstance(plan, Plan):
            raise TypeError(f"plan must be a Plan, got {type(plan).__name__}")
        t_join = check_finite("t_join [s]", t_join)
        if self._phase_t0 + t_join <= self._t_last:
            raise ValueError(f"t_join = {t_join:.6f} s is already streamed (sampled up to "
                             f"{self._t_last - self._phase_t0:.6f} s): expected a later join")
        for what, x, y in zip(("position [m]", "velocity [m/s]", "acceleration [m/s^2]"),
                              self._main.sample(t_join), plan.sample(t_join)):
            if float(np.max(np.abs(np.asarray(x) - np.asarray(y)))) > 1e-9:
                raise ValueError(f"the new plan's {what} at t_join = {t_join:.6f} s is "
                                 f"{np.asarray(y).tolist()}, the running plan's "
                                 f"{np.asarray(x).tolist()}: expected equal")
        self._main = self._phase_plan = plan

    def setpoint(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position [m], velocity [m/s], acceleration [m/s^2] (each (2,)) to command at ``t``
        [s]."""
        t = self._advance(check_finite("t [s]", t))
        if self._phase_plan is None:
            if self._hold is None:
                raise RuntimeError(
                    "no plan and no known position to hold (give home_xz or initial_xz)")
            return self._hold.copy(), np.zeros(2), np.zeros(2)
        return self._phase_plan.sample(t - self._phase_t0)

    def abort(self, t: float, reason: str = "") -> None:
        """Latch an abort at ``t`` [s]: stop at once from the exact current state.

        ``t`` may lie before the newest time sampled (the executed tool pose trails the
        set-points sent ahead of it): within the present phase the stop then starts from the
        phase's state at ``t`` and supersedes what was sampled after it; before the phase
        began, at the newest time sampled.  Ignored (already latched) while stopping or
        holding."""
        if self._state in ("stopping", "holding"):
            return
        t = check_finite("t [s]", t)
        if self._phase_plan is not None and self._phase_t0 <= t < self._t_last:
            self._t_last = t                  # rewind within the phase (the executed state)
        t = self._advance(t)
        self._abort_time, self._abort_reason = t, reason
        if self._phase_plan is None:  # idle without a plan: nothing moves
            self._state, self._final_state, self._rest_time = "holding", "holding", t
            return
        pos, vel, acc = self._phase_plan.sample(t - self._phase_t0)
        home = self.home if self._state != "retracting" else None   # where to retract to
        self._stop = stop_from_state(pos, vel, acc, self._phase_plan.limits)
        self._rest_time = t + self._stop.duration
        self._queue = []
        if home is not None:
            waypoints = [*self.retract_via,
                         Waypoint(float(home[0]), float(home[1]), label="home")]
            rest = self._stop.end
            self._queue.append(("retracting", plan_waypoints(
                rest, waypoints, self.retract_limits)))
        self._phase_plan, self._phase_t0 = self._stop, t
        self._state, self._final_state = "stopping", "holding"
        self._advance(t)

    def hold_after_stop(self) -> None:
        """While ``stopping``: hold where the stop ends instead of retracting after it (a
        planner deactivated mid-run streams no retract, so a retract begun would stay
        ``retracting`` and refuse :meth:`reset`)."""
        if self._state == "stopping":
            self._queue = []

    def reset(self) -> None:
        """Back to ``idle`` (clears the abort).  Only when the tool is at rest
        (``idle``, ``done`` or ``holding``); it then holds where it is."""
        if self._state in MOVING:
            raise RuntimeError(f"reset() refused while {self._state!r}: the tool is moving")
        if self._phase_plan is not None:
            self._hold, self._known_hold = np.asarray(self._phase_plan.end, dtype=float), True
        self._clear()

    # -- internals ----------------------------------------------------------
    def _clear(self) -> None:
        self._state, self._final_state = "idle", "idle"
        self._main = None
        self._stop = None
        self._phase_plan = None
        self._phase_t0 = 0.0
        self._queue = []
        self._t_last = -math.inf
        self._abort_time = None
        self._abort_reason = ""
        self._rest_time = None

    def _advance(self, t: float) -> float:
        """Make ``t`` monotone and step the state machine to it; returns ``t``."""
        t = max(t, self._t_last)
        self._t_last = t
        while self._state in MOVING:
            # start() and abort() set the phase plan of every moving state
            assert self._phase_plan is not None, f"no phase plan while {self._state!r}"
            t_next = self._phase_t0 + self._phase_plan.duration
            if t < t_next:
                break
            if self._queue:
                self._state, self._phase_plan = self._queue.pop(0)
                self._phase_t0 = t_next
            else:
                self._state = self._final_state
        return t
