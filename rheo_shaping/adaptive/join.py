"""Plans that start from a moving tool and join the plan it follows without a jump.

A re-plan at time t_j starts from the set-point state (p, v, a) of the running plan at
t_j.  Its first piece is one ruckig state-to-state trajectory (position interface, target
at rest) from that state to the move's target, phase-synchronised along the move's line
with the path limits scaled by the direction cosines (as
:func:`rheo_shaping.planning.pieces.line_trajectory` does from rest); a velocity above the
new v_max is first brought down by ruckig's brake pre-profile.  Position, velocity and
acceleration are those of the running plan at t_j, so the joined plan has no jump in
set-point, velocity or acceleration, and its jerk stays within the limits.
:func:`splice` makes the one plan from t = 0 a streamer plays (the old plan before t_j, the
new one after).  No ROS here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..params.validators import check_finite, check_point
from ..planning.limits import MotionLimits
from ..planning.pieces import AxisBuilder, append_trajectory, as_point, calculate, line_input
from ..planning.plans import MIN_MOVE_M, Plan, Segment, Waypoint, assemble_plan


@dataclass(frozen=True)
class ToolState:
    """The tool's set-point state at a time: position [m], velocity [m/s], acceleration
    [m/s^2], each (x, z)."""

    position: tuple[float, float]
    velocity: tuple[float, float]
    acceleration: tuple[float, float]

    @classmethod
    def of(cls, plan: Plan, t: float) -> "ToolState":
        """``plan``'s state at its time ``t`` [s]."""
        p, v, a = plan.sample(t)
        return cls(as_point(p), as_point(v), as_point(a))

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return (check_point("ToolState.position [m]", self.position),
                check_point("ToolState.velocity [m/s]", self.velocity),
                check_point("ToolState.acceleration [m/s^2]", self.acceleration))


def _from_state(p: np.ndarray, v: np.ndarray, a: np.ndarray, target: np.ndarray,
                limits: MotionLimits):
    """The ruckig trajectory from (p, v, a) to rest at ``target`` along the line."""
    d = target - p
    dist = float(np.linalg.norm(d))
    u = d / dist if dist > MIN_MOVE_M else v / max(float(np.linalg.norm(v)), 1e-300)
    return calculate(line_input(p, v, a, target, u, limits))


def plan_from_state(state: ToolState, first: Waypoint | None, waypoints: Sequence[Waypoint],
                    limits: MotionLimits, first_dwell: float = 0.0, first_label: str = ""
                    ) -> tuple[Plan, tuple[int, ...]]:
    """A plan from the tool's ``state`` (time 0 of the plan): with ``first``, a ruckig
    trajectory from the state to rest at ``first`` (its limits or ``limits``) and its
    dwell; else (the tool at rest) a dwell of ``first_dwell`` [s] labelled ``first_label``;
    then ``waypoints`` from
    rest as :func:`~rheo_shaping.planning.plans.plan_waypoints` does (labels as given).
    Returns the plan and, for each of its segments, whose it is (0: ``first`` or the first
    dwell, i: ``waypoints[i - 1]``)."""
    p, v, a = state.arrays()
    first_dwell = check_finite("first_dwell [s]", first_dwell, non_negative=True)
    if first is None and (np.any(v != 0.0) or np.any(a != 0.0)):
        raise ValueError(f"state velocity {v.tolist()} m/s, acceleration {a.tolist()} m/s^2: "
                         "expected rest when no first waypoint is given")
    axes = (AxisBuilder(p[0]), AxisBuilder(p[1]))
    segments: list[Segment] = []
    owners: list[int] = []
    t = 0.0
    here = p
    if first is not None:
        traj = _from_state(p, v, a, first.xz, first.limits or limits)
        here = append_trajectory(axes, traj, 0.0)
        segments.append(Segment(0.0, traj.duration, "move", as_point(p), as_point(first.xz),
                                first.label))
        owners.append(0)
        t = traj.duration
        first_dwell = first.dwell_s
        label = first.label
    else:
        label = first_label
    if first_dwell > 0.0:
        segments.append(Segment(t, t + first_dwell, "dwell", as_point(here), as_point(here),
                                label))
        owners.append(0)
        t += first_dwell
    for i, wp in enumerate(waypoints, start=1):
        target = wp.xz
        if float(np.linalg.norm(target - here)) > MIN_MOVE_M:
            traj = _from_state(here, np.zeros(2), np.zeros(2), target, wp.limits or limits)
            end = append_trajectory(axes, traj, t)
            segments.append(Segment(t, t + traj.duration, "move", as_point(here),
                                    as_point(target), wp.label))
            owners.append(i)
            t += traj.duration
            here = end
        if wp.dwell_s > 0.0:
            segments.append(Segment(t, t + wp.dwell_s, "dwell", as_point(target),
                                    as_point(target), wp.label))
            owners.append(i)
            t += wp.dwell_s
    return assemble_plan(segments, t, limits, p, axes), tuple(owners)


def splice(old: Plan, t_join: float, new: Plan) -> Plan:
    """One plan from t = 0: ``old`` before ``t_join`` [s], ``new`` (its time 0 at
    ``t_join``) after.  ``new`` must start in ``old``'s state at ``t_join`` (1e-9 m,
    1e-9 m/s, 1e-9 m/s^2); a ValueError says what differs."""
    t_join = check_finite("t_join [s]", t_join)
    s_old, s_new = ToolState.of(old, t_join), ToolState.of(new, 0.0)
    for what, x, y in zip(("position [m]", "velocity [m/s]", "acceleration [m/s^2]"),
                          s_old.arrays(), s_new.arrays()):
        if float(np.max(np.abs(x - y))) > 1e-9:
            raise ValueError(f"splice: the new plan's {what} {y.tolist()} differs from the old "
                             f"plan's {x.tolist()} at t_join = {t_join!r} s: expected equal")
    axes = (AxisBuilder(0.0), AxisBuilder(0.0))
    for k in range(2):
        po, pn = old._axes[k], new._axes[k]
        axes[k].rows = [(float(po.t0[i]), float(po.p0[i]), float(po.v0[i]), float(po.a0[i]),
                         float(po.j[i])) for i in range(len(po.t0)) if po.t0[i] < t_join]
        if not axes[k].rows:
            x0, v0, a0 = po.evaluate_one(0.0)
            axes[k].rows = [(0.0, float(x0), float(v0), float(a0), 0.0)]
        for i in range(len(pn.t0)):
            axes[k].add(t_join + float(pn.t0[i]), float(pn.p0[i]), float(pn.v0[i]),
                        float(pn.a0[i]), float(pn.j[i]))
    segs = [Segment(s.t_start, min(s.t_end, t_join), s.kind, s.start, s.end, s.label)
            for s in old.segments if s.t_start < t_join]
    segs += [Segment(t_join + s.t_start, t_join + s.t_end, s.kind, s.start, s.end, s.label)
             for s in new.segments]
    duration = t_join + new.duration
    if not math.isfinite(duration):
        raise ValueError(f"splice: duration {duration!r} s: expected finite")
    return assemble_plan(segs, duration, old.limits, old.start, axes)
