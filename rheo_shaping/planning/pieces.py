"""The ruckig side of a plan: per-axis piecewise-cubic motion and its assembly.

A straight rest-to-rest segment is one offline ruckig calculation, phase-synchronised
with per-axis limits scaled by the direction cosines (a straight line); its phases
become the :class:`Pieces` of each axis, which sample the motion exactly.  Shared by
:mod:`rheo_shaping.planning.plans` (plans) and :mod:`rheo_shaping.planning.stopping`
(stops from any state).  No ROS imports here.
"""
from __future__ import annotations

import bisect
from dataclasses import dataclass, field

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Synchronization, Trajectory

from ..params.validators import PointLike
from .limits import MotionLimits


@dataclass(frozen=True, eq=False)
class Pieces:
    """Piecewise-cubic motion of one axis: piece k starts at ``t0[k]`` [s]
    with position ``p0`` [m], velocity ``v0`` [m/s], acceleration ``a0``
    [m/s^2] and constant jerk ``j`` [m/s^3]; the last piece lasts forever."""

    t0: np.ndarray
    p0: np.ndarray
    v0: np.ndarray
    a0: np.ndarray
    j: np.ndarray
    # made by __post_init__, for evaluate_one: t0 as a list, the rows (p0, v0, a0, j)
    _t0_list: list[float] = field(init=False, repr=False)
    _rows: list[tuple[float, float, float, float]] = field(init=False, repr=False)

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
            self, "_rows", list(zip(self.p0.tolist(), self.v0.tolist(),
                                self.a0.tolist(), self.j.tolist()))
        )


class AxisBuilder:
    """Accumulates the pieces of one axis while a plan is built."""

    def __init__(self, p: float) -> None:
        self.rows: list[tuple[float, float, float, float, float]] = [(0.0, p, 0.0, 0.0, 0.0)]

    def add(self, t0: float, p: float, v: float, a: float, j: float) -> None:
        if self.rows and self.rows[-1][0] == t0:
            self.rows.pop()
        self.rows.append((t0, p, v, a, j))

    def build(self) -> Pieces:
        arr = np.array(self.rows, dtype=float)
        return Pieces(arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3], arr[:, 4])


def line_trajectory(p0: np.ndarray, p1: np.ndarray, limits: MotionLimits) -> Trajectory:
    """Straight rest-to-rest ruckig trajectory from ``p0`` to ``p1`` [m]."""
    d = p1 - p0
    u = d / np.linalg.norm(d)
    traj = calculate(line_input(p0, np.zeros(2), np.zeros(2), p1, u, limits))
    check_phase_synchronised(traj, d)
    return traj


def line_input(p0: np.ndarray, v0: np.ndarray, a0: np.ndarray, p1: np.ndarray,
               u: np.ndarray, limits: MotionLimits) -> InputParameter:
    """Ruckig input from position ``p0`` [m], velocity ``v0`` [m/s], acceleration ``a0``
    [m/s^2] to rest at ``p1`` [m], phase-synchronised along direction ``u`` (the path
    limits scaled by its direction cosines)."""
    inp = InputParameter(2)
    inp.current_position = p0.tolist()
    inp.current_velocity = v0.tolist()
    inp.current_acceleration = a0.tolist()
    inp.target_position = p1.tolist()
    inp.target_velocity = [0.0, 0.0]
    inp.target_acceleration = [0.0, 0.0]
    c = axis_scale(u)
    inp.max_velocity = (limits.v_max * c).tolist()
    inp.max_acceleration = (limits.a_max * c).tolist()
    inp.max_jerk = (limits.j_max * c).tolist()
    inp.synchronization = Synchronization.Phase
    return inp


def axis_scale(u: np.ndarray) -> np.ndarray:
    """|direction cosines|; an axis that does not move keeps the full limit
    (ruckig refuses zero limits, and it stays put anyway)."""
    c = np.abs(np.asarray(u, dtype=float))
    return np.where(c > 0.0, c, 1.0)


def calculate(inp: InputParameter) -> Trajectory:
    """Offline ruckig calculation; raises ``RuntimeError`` when it fails."""
    traj = Trajectory(2)
    try:
        result = Ruckig(2).calculate(inp, traj)
    except RuntimeError as exc:  # ruckig.RuckigError derives from RuntimeError
        raise RuntimeError(f"ruckig failed: {exc}") from exc
    if result not in (Result.Working, Result.Finished):
        raise RuntimeError(f"ruckig failed with {result}")
    return traj


def check_phase_synchronised(traj: Trajectory, d: np.ndarray) -> None:
    """Both moving axes must share their phase times (a straight line)."""
    profs = traj.profiles[0]
    moving = [k for k in range(2) if d[k] != 0.0]
    if len(moving) == 2:
        t0, t1 = np.asarray(profs[0].t), np.asarray(profs[1].t)
        if not np.allclose(t0, t1, rtol=1e-9, atol=1e-12 * max(traj.duration, 1.0)):
            raise RuntimeError(f"ruckig did not phase-synchronise the segment: {t0} vs {t1}")


def append_trajectory(axes: tuple[AxisBuilder, AxisBuilder], traj: Trajectory,
                      t_start: float) -> np.ndarray:
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


def as_point(p: PointLike) -> tuple[float, float]:
    return (float(p[0]), float(p[1]))
