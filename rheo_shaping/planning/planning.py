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

import bisect
import math
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Synchronization, Trajectory

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
class MotionLimits:
    """Path limits of the tool: ``v_max`` [m/s], ``a_max`` [m/s^2], ``j_max`` [m/s^3].

    They bound the Euclidean norm of the tool's velocity, acceleration and
    jerk in the x-z plane.  Each must be finite and > 0.
    """

    v_max: float
    a_max: float
    j_max: float

    def __post_init__(self) -> None:
        for name, unit in (("v_max", "m/s"), ("a_max", "m/s^2"), ("j_max", "m/s^3")):
            _check_positive_finite(f"MotionLimits.{name} [{unit}]", getattr(self, name))

    def scaled(self, factor: float) -> "MotionLimits":
        """All three limits multiplied by ``factor`` (> 0)."""
        _check_positive_finite("factor [-]", factor)
        return MotionLimits(self.v_max * factor, self.a_max * factor, self.j_max * factor)


@dataclass(frozen=True)
class Waypoint:
    """A point ``(x, z)`` [m] in frame ``cake`` reached at rest, then ``dwell_s`` [s] of stop."""

    x: float
    z: float
    dwell_s: float = 0.0
    label: str = ""
    limits: "MotionLimits | None" = None   # limits of the move to this waypoint (default: the plan's)

    def __post_init__(self) -> None:
        _check_finite("Waypoint.x [m]", self.x)
        _check_finite("Waypoint.z [m]", self.z)
        v = _as_float("Waypoint.dwell_s [s]", self.dwell_s)
        if not math.isfinite(v) or v < 0.0:
            raise ValueError(
                f"Waypoint.dwell_s [s] = {self.dwell_s!r} is out of range: expected a finite value >= 0"
            )

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
class _Pieces:
    """Piecewise-cubic motion of one axis: piece k starts at ``t0[k]`` [s]
    with position ``p0`` [m], velocity ``v0`` [m/s], acceleration ``a0``
    [m/s^2] and constant jerk ``j`` [m/s^3]; the last piece lasts forever."""

    t0: np.ndarray
    p0: np.ndarray
    v0: np.ndarray
    a0: np.ndarray
    j: np.ndarray

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity, acceleration at times ``t`` (array) [s]."""
        k = np.searchsorted(self.t0, t, side="right") - 1
        np.clip(k, 0, len(self.t0) - 1, out=k)
        dt = t - self.t0[k]
        p0, v0, a0, j = self.p0[k], self.v0[k], self.a0[k], self.j[k]
        pos = p0 + dt * (v0 + dt * (0.5 * a0 + dt * j / 6.0))
        vel = v0 + dt * (a0 + 0.5 * dt * j)
        acc = a0 + dt * j
        return pos, vel, acc

    def evaluate_one(self, t: float) -> tuple[float, float, float]:
        """Scalar :meth:`evaluate` (no numpy overhead)."""
        k = max(bisect.bisect_right(self._t0_list, t) - 1, 0)
        dt = t - self._t0_list[k]
        p0, v0, a0, j = self._rows[k]
        return (
            p0 + dt * (v0 + dt * (0.5 * a0 + dt * j / 6.0)),
            v0 + dt * (a0 + 0.5 * dt * j),
            a0 + dt * j,
        )

    def __post_init__(self) -> None:
        for name in ("t0", "p0", "v0", "a0", "j"):
            arr = np.array(getattr(self, name), dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "_t0_list", self.t0.tolist())
        object.__setattr__(
            self, "_rows", list(zip(self.p0.tolist(), self.v0.tolist(), self.a0.tolist(), self.j.tolist()))
        )


class _AxisBuilder:
    """Accumulates the pieces of one axis while a plan is built."""

    def __init__(self, p: float) -> None:
        self.rows: list[tuple[float, float, float, float, float]] = [(0.0, p, 0.0, 0.0, 0.0)]

    def add(self, t0: float, p: float, v: float, a: float, j: float) -> None:
        if self.rows and self.rows[-1][0] == t0:
            self.rows.pop()
        self.rows.append((t0, p, v, a, j))

    def build(self) -> _Pieces:
        arr = np.array(self.rows, dtype=float)
        return _Pieces(arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3], arr[:, 4])


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
    _axes: tuple[_Pieces, _Pieces] = field(repr=False)

    # -- sampling ---------------------------------------------------------
    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position [m], velocity [m/s], acceleration [m/s^2], each (2,), at time ``t`` [s] (clamped)."""
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
        _check_positive_finite("dt [s]", dt)
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
    start_xz: Sequence[float],
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
    p = _xz("start_xz [m]", start_xz)
    axes = (_AxisBuilder(p[0]), _AxisBuilder(p[1]))
    nominal = _pt(p)
    segments: list[Segment] = []
    t = 0.0
    for i, wp in enumerate(waypoints):
        if not isinstance(wp, Waypoint):
            raise TypeError(f"waypoints[{i}] must be a Waypoint, got {type(wp).__name__}")
        target = wp.xz
        move_label, dwell_label = _labels(wp, i, label_phases)
        if float(np.linalg.norm(target - p)) > MIN_MOVE_M:
            traj = _line_trajectory(p, target, wp.limits or limits)
            p = _append_trajectory(axes, traj, t)
            segments.append(Segment(t, t + traj.duration, "move", nominal, _pt(target), move_label))
            t += traj.duration
            nominal = _pt(target)
        if wp.dwell_s > 0.0:
            segments.append(Segment(t, t + wp.dwell_s, "dwell", _pt(target), _pt(target), dwell_label))
            t += wp.dwell_s
    return _finish(segments, t, limits, start_xz, axes)


def rest_to_rest_time(distance: float, limits: MotionLimits) -> float:
    """Time-optimal jerk-limited rest-to-rest time [s] over ``distance`` [m].

    With cruise and both acceleration trapezoids reached:
    ``T = D/v + v/a + a/j``.  The other cases (no cruise, triangular
    acceleration) are handled too.
    """
    d = _as_float("distance [m]", distance)
    if not math.isfinite(d) or d < 0.0:
        raise ValueError(f"distance [m] = {distance!r} is out of range: expected a finite value >= 0")
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


def _line_trajectory(p0: np.ndarray, p1: np.ndarray, limits: MotionLimits) -> Trajectory:
    """Straight rest-to-rest ruckig trajectory from ``p0`` to ``p1`` [m]."""
    d = p1 - p0
    u = d / np.linalg.norm(d)
    inp = InputParameter(2)
    inp.current_position = p0.tolist()
    inp.current_velocity = [0.0, 0.0]
    inp.current_acceleration = [0.0, 0.0]
    inp.target_position = p1.tolist()
    inp.target_velocity = [0.0, 0.0]
    inp.target_acceleration = [0.0, 0.0]
    c = _axis_scale(u)
    inp.max_velocity = (limits.v_max * c).tolist()
    inp.max_acceleration = (limits.a_max * c).tolist()
    inp.max_jerk = (limits.j_max * c).tolist()
    inp.synchronization = Synchronization.Phase
    traj = _calculate(inp)
    _check_phase_synchronised(traj, d)
    return traj


def _axis_scale(u: np.ndarray) -> np.ndarray:
    """|direction cosines|; an axis that does not move keeps the full limit
    (ruckig refuses zero limits, and it stays put anyway)."""
    c = np.abs(np.asarray(u, dtype=float))
    return np.where(c > 0.0, c, 1.0)


def _calculate(inp: InputParameter) -> Trajectory:
    """Offline ruckig calculation; raises ``RuntimeError`` when it fails."""
    traj = Trajectory(2)
    try:
        result = Ruckig(2).calculate(inp, traj)
    except RuntimeError as exc:  # ruckig.RuckigError derives from RuntimeError
        raise RuntimeError(f"ruckig failed: {exc}") from exc
    if result not in (Result.Working, Result.Finished):
        raise RuntimeError(f"ruckig failed with {result}")
    return traj


def _check_phase_synchronised(traj: Trajectory, d: np.ndarray) -> None:
    """Both moving axes must share their phase times (a straight line)."""
    profs = traj.profiles[0]
    moving = [k for k in range(2) if d[k] != 0.0]
    if len(moving) == 2:
        t0, t1 = np.asarray(profs[0].t), np.asarray(profs[1].t)
        if not np.allclose(t0, t1, rtol=1e-9, atol=1e-12 * max(traj.duration, 1.0)):
            raise RuntimeError(f"ruckig did not phase-synchronise the segment: {t0} vs {t1}")


def _append_trajectory(axes: tuple[_AxisBuilder, _AxisBuilder], traj: Trajectory, t_start: float) -> np.ndarray:
    """Copy a single-section ruckig trajectory that ends at rest into the axis
    builders, shifted by ``t_start`` [s]; returns its end position (2,) [m]."""
    end = np.empty(2)
    for k, prof in enumerate(traj.profiles[0]):
        t = t_start
        brake = prof.brake
        if brake.duration > 0.0:
            for i in range(2):
                if brake.t[i] > 0.0:
                    axes[k].add(t, brake.p[i], brake.v[i], brake.a[i], brake.j[i])
                    t += brake.t[i]
        for i in range(7):
            if prof.t[i] > 0.0:
                axes[k].add(t, prof.p[i], prof.v[i], prof.a[i], prof.j[i])
                t += prof.t[i]
        end[k] = prof.p[7]
        # ruckig's target state is rest (v = a = 0 up to ~1e-19): hold exactly,
        # at the latest when the segment ends (the summed phase times may
        # exceed the duration by round-off).
        axes[k].add(min(t, t_start + traj.duration), prof.p[7], 0.0, 0.0, 0.0)
    return end


def _finish(segments: list[Segment], duration: float, limits: MotionLimits,
            start_xz: Sequence[float], axes: tuple[_AxisBuilder, _AxisBuilder]) -> Plan:
    return Plan(tuple(segments), float(duration), limits, _pt(start_xz), (axes[0].build(), axes[1].build()))


def _labels(wp: Waypoint, i: int, label_phases: bool) -> tuple[str, str]:
    if not label_phases:
        return wp.label, wp.label
    return (wp.label or f"move{i}", f"{wp.label}:dwell" if wp.label else f"dwell{i}")


def _pt(p: Sequence[float]) -> tuple[float, float]:
    return (float(p[0]), float(p[1]))


def _xz(name: str, p: Sequence[float]) -> np.ndarray:
    arr = np.asarray(p, dtype=float).reshape(-1)
    if arr.shape != (2,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} = {p!r} is out of range: expected two finite numbers (x, z)")
    return arr


def _as_float(name: str, value: float) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r}: expected a number") from None


def _check_finite(name: str, value: float) -> None:
    if not math.isfinite(_as_float(name, value)):
        raise ValueError(f"{name} = {value!r} is out of range: expected a finite value")


def _check_positive_finite(name: str, value: float) -> None:
    v = _as_float(name, value)
    if not math.isfinite(v) or v <= 0.0:
        raise ValueError(f"{name} = {value!r} is out of range: expected a finite value > 0")


#: Nominal cell limits: the paper's 1e-3 m/s tool speed.
DEFAULT_LIMITS = MotionLimits(v_max=1e-3, a_max=5e-3, j_max=5e-2)
#: Slow retract after an abort.
DEFAULT_RETRACT_LIMITS = MotionLimits(v_max=2e-3, a_max=2.5e-3, j_max=2.5e-2)
