"""Jerk-limited straight-line tool plans in the vertical plane (frame ``cake``).

The tool moves in the x-z plane (x horizontal, z up; SI units).  A plan goes
from rest at a start point through a list of :class:`Waypoint` s, coming to
rest at each one and dwelling there (the paper's Sec. 5 movements: approach,
forced deformation, a 15-30 s stop at the end of travel, retract).

Every motion segment is one ruckig state-to-state trajectory computed offline
(``Ruckig(2).calculate``; the community edition has no intermediate
waypoints).  Phase synchronisation with per-axis limits scaled by the
direction cosines of the segment makes the motion a straight line whose path
speed, acceleration and jerk respect :class:`MotionLimits` (cruise at exactly
``v_max`` when the segment is long enough).

A :class:`Plan` keeps the piecewise-cubic polynomials ruckig returned (the
profiles' phase states and jerks), so it can be sampled exactly at any time,
one point at a time or vectorised.  Stops and the online streamer live in
:mod:`rheo_shaping.planning.stopping`.  No ROS imports here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np
from ..params.validators import (PointLike, check_finite, check_non_negative, check_point,
                                 check_positive)
from .limits import MotionLimits
from .pieces import AxisBuilder, Pieces, append_trajectory, as_point, line_trajectory

__all__ = [
    "MotionLimits",
    "Waypoint",
    "Segment",
    "Plan",
    "plan_waypoints",
    "rest_to_rest_time",
    "MIN_MOVE_M",
    "DEFAULT_LIMITS",
    "DEFAULT_RETRACT_LIMITS",
]

#: A move shorter than this [m] is treated as already done (no segment).
MIN_MOVE_M = 1e-12


@dataclass(frozen=True)
class Waypoint:
    """A point ``(x, z)`` [m] in frame ``cake`` reached at rest, then ``dwell_s`` [s] of stop."""

    x: float
    z: float
    dwell_s: float = 0.0
    label: str = ""
    # limits of the move to this waypoint (default: the plan's)
    limits: "MotionLimits | None" = None

    def __post_init__(self) -> None:
        check_finite("Waypoint.x [m]", self.x)
        check_finite("Waypoint.z [m]", self.z)
        check_non_negative("Waypoint.dwell_s [s]", self.dwell_s)

    @property
    def xz(self) -> np.ndarray:
        """Position as an array (2,) [m]."""
        return np.array([self.x, self.z], dtype=float)


@dataclass(frozen=True)
class Segment:
    """One piece of a plan: a straight ``"move"`` or a ``"dwell"`` at rest.

    Times [s] are relative to the plan's start; ``start``/``end`` [m] are the
    nominal (x, z) points.
    """

    t_start: float
    t_end: float
    kind: str
    start: tuple[float, float]
    end: tuple[float, float]
    label: str = ""

    @property
    def duration(self) -> float:
        """``t_end - t_start`` [s]."""
        return self.t_end - self.t_start


@dataclass(frozen=True, eq=False)
class Plan:
    """An immutable, exactly sampled tool motion starting at t = 0 [s].

    Times are clamped to ``[0, duration]``: before 0 the state at 0 (rest at
    the start for a waypoint plan), after ``duration`` rest at the end.
    """

    segments: tuple[Segment, ...]
    duration: float
    limits: MotionLimits
    start: tuple[float, float]
    _axes: tuple[Pieces, Pieces] = field(repr=False)

    # -- sampling ---------------------------------------------------------
    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position [m], velocity [m/s], acceleration [m/s^2], each (2,), at time ``t`` [s]
        (clamped)."""
        t = float(t)
        if math.isnan(t):
            raise ValueError("Plan.sample: t is NaN")
        if t >= self.duration:
            return np.array(self.end), np.zeros(2), np.zeros(2)
        t = max(t, 0.0)
        x = self._axes[0].evaluate_one(t)
        z = self._axes[1].evaluate_one(t)
        return np.array([x[0], z[0]]), np.array([x[1], z[1]]), np.array([x[2], z[2]])

    def sample_many(self, times: Iterable[float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Vectorised :meth:`sample`: arrays (n, 2) of positions, velocities, accelerations."""
        t = np.asarray(times, dtype=float).reshape(-1)
        if np.isnan(t).any():
            raise ValueError("Plan.sample_many: times contain NaN")
        tc = np.clip(t, 0.0, self.duration)
        out = [np.empty((t.size, 2)) for _ in range(3)]
        for i, axis in enumerate(self._axes):
            for arr, col in zip(out, axis.evaluate(tc)):
                arr[:, i] = col
        rest = t >= self.duration
        if rest.any():
            out[0][rest] = self.end
            out[1][rest] = 0.0
            out[2][rest] = 0.0
        return out[0], out[1], out[2]

    def to_arrays(self, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Times (n,) [s] on a grid of step ``dt`` [s] from 0, ending with ``duration``;
        positions (n, 2) [m]; velocities (n, 2) [m/s]."""
        check_positive("dt [s]", dt)
        n = int(math.floor(self.duration / dt + 1e-9))
        times = dt * np.arange(n + 1, dtype=float)
        if self.duration - times[-1] > 1e-9 * dt:
            times = np.append(times, self.duration)
        else:
            times[-1] = min(times[-1], self.duration)
        pos, vel, _ = self.sample_many(times)
        return times, pos, vel

    # -- structure ----------------------------------------------------------
    @property
    def end(self) -> tuple[float, float]:
        """Where the plan comes to rest [m] (the exact end state of the last move)."""
        return (float(self._axes[0].p0[-1]), float(self._axes[1].p0[-1]))

    def knots(self, include_phases: bool = False) -> np.ndarray:
        """Sorted times [s] where motion segments start or stop (plus 0 and ``duration``).

        With ``include_phases`` also every time where ruckig switches jerk.
        """
        ts = {0.0, float(self.duration)}
        for s in self.segments:
            if s.kind == "move":
                ts.update((s.t_start, s.t_end))
        if include_phases:
            for axis in self._axes:
                ts.update(float(t) for t in axis.t0)
        return np.array(sorted(ts), dtype=float)

    @property
    def max_speed(self) -> float:
        """Largest path speed [m/s] over the plan (exact for straight-line moves)."""
        cand = [self.knots(include_phases=True)]
        for axis in self._axes:
            with np.errstate(divide="ignore", invalid="ignore"):
                tz = axis.t0 - axis.a0 / axis.j  # where this axis' acceleration crosses zero
            ok = np.isfinite(tz) & (tz > 0.0) & (tz < self.duration)
            cand.append(tz[ok])
        _, vel, _ = self.sample_many(np.concatenate(cand))
        return float(np.max(np.linalg.norm(vel, axis=1), initial=0.0))


# -- building plans ------------------------------------------------------------


def plan_waypoints(
    start_xz: PointLike,
    waypoints: Sequence[Waypoint],
    limits: MotionLimits,
    *,
    label_phases: bool = True,
) -> Plan:
    """Plan from rest at ``start_xz`` [m] through ``waypoints``, at rest at each.

    Each waypoint gets a straight, jerk-limited ``"move"`` segment (none if it
    is within ``MIN_MOVE_M`` of the current point) and then a ``"dwell"`` of
    ``dwell_s`` (none if zero).  With ``label_phases`` the segments are
    labelled ``"<label>"`` / ``"<label>:dwell"`` (``"move<i>"`` / ``"dwell<i>"``
    for unlabelled waypoints); otherwise they carry the waypoint's label as is.
    """
    if not isinstance(limits, MotionLimits):
        raise TypeError(f"limits must be a MotionLimits, got {type(limits).__name__}")
    p = check_point("start_xz [m]", start_xz)
    axes = (AxisBuilder(p[0]), AxisBuilder(p[1]))
    nominal = as_point(p)
    segments: list[Segment] = []
    t = 0.0
    for i, wp in enumerate(waypoints):
        if not isinstance(wp, Waypoint):
            raise TypeError(f"waypoints[{i}] must be a Waypoint, got {type(wp).__name__}")
        target = wp.xz
        move_label, dwell_label = _labels(wp, i, label_phases)
        if float(np.linalg.norm(target - p)) > MIN_MOVE_M:
            traj = line_trajectory(p, target, wp.limits or limits)
            p = append_trajectory(axes, traj, t)
            segments.append(Segment(t, t + traj.duration, "move",
                            nominal, as_point(target), move_label))
            t += traj.duration
            nominal = as_point(target)
        if wp.dwell_s > 0.0:
            segments.append(Segment(t, t + wp.dwell_s, "dwell",
                            as_point(target), as_point(target), dwell_label))
            t += wp.dwell_s
    return assemble_plan(segments, t, limits, start_xz, axes)


def rest_to_rest_time(distance: float, limits: MotionLimits) -> float:
    """Time-optimal jerk-limited rest-to-rest time [s] over ``distance`` [m].

    With cruise and both acceleration trapezoids reached:
    ``T = D/v + v/a + a/j``.  The other cases (no cruise, triangular
    acceleration) are handled too.
    """
    d = check_non_negative("distance [m]", distance)
    v, a, j = limits.v_max, limits.a_max, limits.j_max
    if v >= a * a / j:  # a_max is reached on the way to v_max
        if d >= v * (v / a + a / j):
            return d / v + v / a + a / j
        vp = 0.5 * a * (-a / j + math.sqrt((a / j) ** 2 + 4.0 * d / a))  # peak speed
        if vp >= a * a / j:
            return 2.0 * (vp / a + a / j)
    elif d >= 2.0 * v * math.sqrt(v / j):
        return d / v + 2.0 * math.sqrt(v / j)
    return 4.0 * (d / (2.0 * j)) ** (1.0 / 3.0)


# -- internals ---------------------------------------------------------------


def assemble_plan(segments: list[Segment], duration: float, limits: MotionLimits,
                  start_xz: PointLike, axes: tuple[AxisBuilder, AxisBuilder]) -> Plan:
    return Plan(tuple(segments), float(duration), limits, as_point(start_xz),
                (axes[0].build(), axes[1].build()))


def _labels(wp: Waypoint, i: int, label_phases: bool) -> tuple[str, str]:
    if not label_phases:
        return wp.label, wp.label
    return (wp.label or f"move{i}", f"{wp.label}:dwell" if wp.label else f"dwell{i}")


#: Nominal cell limits: the paper's 1e-3 m/s tool speed.
DEFAULT_LIMITS = MotionLimits(v_max=1e-3, a_max=5e-3, j_max=5e-2)
#: Slow retract after an abort.
DEFAULT_RETRACT_LIMITS = MotionLimits(v_max=2e-3, a_max=2.5e-3, j_max=2.5e-2)
