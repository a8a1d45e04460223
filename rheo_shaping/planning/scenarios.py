"""The paper's shaping movements 1-4 (Sec. 5, Fig. 14) as tool moves.

A scenario is the tool's start point and a list of straight moves, each at a
path speed and followed by a dwell.  Movements 1-3 go from their start to the
end of travel in one straight line (vertical, horizontal, 45 deg), stop for
``movement.dwell`` and go back.  Movement 4 (2-step) goes down vertically
with the tool's inner face at distance ``d`` from the cake wall, stops for
half the dwell, goes horizontally to the end of travel, stops for the other
half, and goes back the way it came.  Movement 0 follows the user's
waypoints.  The moves become a jerk-limited ruckig plan in
:func:`scenario_plan`, or a piecewise-linear path in :func:`scenario_polyline`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..params.cell import CellParams, MovementParams
from .plans import MotionLimits, Plan, Waypoint, plan_waypoints
from ..sheet.paths import PolylinePath
from ..sheet.tools import tool_shape


#: The phases of a movement (paper Sec. 5), as plans, runs and reports name them, and
#: how they are called for people (plots, tables): the one phase vocabulary.
PHASES = {"approach": "approach", "forced": "forced deformation", "dwell": "dwell",
          "release": "release", "settle": "settle"}
#: A move that deforms the sheet has a label starting with FORCED; the way back is RETRACT.
FORCED, RETRACT = "forced", "retract"


def phase_label(name: str) -> str:
    """The words for phase ``name`` (itself when it is not one of :data:`PHASES`)."""
    return PHASES.get(name, name)


@dataclass(frozen=True)
class Move:
    """A straight move to ``target`` (x, z) [m] at ``speed`` [m/s], then ``dwell`` [s]."""

    target: tuple[float, float]
    speed: float
    dwell: float = 0.0
    label: str = ""


@dataclass(frozen=True)
class Scenario:
    """Where the tool starts and how it moves."""

    start: tuple[float, float]
    moves: tuple[Move, ...]


def tool_inner_offset(params: CellParams) -> float:
    """Distance [m] from the tool's reference point to its face nearest the wall (-x)."""
    outline = tool_shape(params.tool).outline(256)
    return float(-np.min(outline[:, 0]))


def movement_scenario(params: CellParams, number: int | None = None,
                      speed: float | None = None, dwell: float | None = None,
                      d: float | None = None) -> Scenario:
    """The paper's movement ``number`` (default ``movement.number``) on this cell."""
    mv: MovementParams = params.movement
    number = mv.number if number is None else int(number)
    speed = mv.speed if speed is None else float(speed)
    dwell = mv.dwell if dwell is None else float(dwell)
    back = mv.retract_speed
    if number in (1, 2, 3):
        start = tuple(getattr(mv, f"start_{number}"))
        end = tuple(getattr(mv, f"end_{number}"))
        return Scenario(start,
                        (Move(end, speed, dwell, FORCED), Move(start, back, 0.0, RETRACT)))
    if number == 4:
        d = mv.d if d is None else float(d)
        x_v = d + tool_inner_offset(params)
        start = (x_v, mv.start_4[1])
        corner = (x_v, mv.end_4[1])
        end = tuple(mv.end_4)
        return Scenario(start, (
            Move(corner, speed, 0.5 * dwell, f"{FORCED}_vertical"),
            Move(end, speed, 0.5 * dwell, f"{FORCED}_horizontal"),
            Move(corner, back, 0.0, RETRACT),
            Move(start, back, 0.0, RETRACT)))
    if number == 0:
        pts = np.asarray(mv.waypoints, float).reshape(-1, 2)
        dwells = list(mv.dwells) + [0.0] * (len(pts) - len(mv.dwells))
        home = tuple(params.tool.home)
        moves = [Move(tuple(p), speed, dw, f"waypoint_{i}")
                 for i, (p, dw) in enumerate(zip(pts, dwells))]
        moves.append(Move(home, back, 0.0, RETRACT))
        return Scenario(home, tuple(moves))
    raise ValueError(
        f"parameter 'movement.number' = {number!r} is invalid: expected 0, 1, 2, 3 or 4")


def scenario_polyline(scenario: Scenario) -> PolylinePath:
    """Constant-speed straight moves with instant starts and stops."""
    t, pts = [0.0], [np.asarray(scenario.start, float)]
    for mv in scenario.moves:
        target = np.asarray(mv.target, float)
        t.append(t[-1] + float(np.hypot(*(target - pts[-1]))) / mv.speed)
        pts.append(target)
        if mv.dwell > 0:
            t.append(t[-1] + mv.dwell)
            pts.append(target)
    return PolylinePath(np.array(t), np.array(pts))


def movement_limits(params: CellParams, speed: float) -> MotionLimits:
    """Path limits of a move at ``speed`` [m/s] with the cell's acceleration and jerk limits."""
    return MotionLimits(speed, params.movement.accel, params.movement.jerk)


def scenario_plan(params: CellParams, scenario: Scenario) -> "ScenarioPlan":
    """The scenario as one jerk-limited ruckig plan (rest at every waypoint)."""
    waypoints = [Waypoint(float(m.target[0]), float(m.target[1]), m.dwell, m.label,
                          movement_limits(params, m.speed)) for m in scenario.moves]
    plan = plan_waypoints(scenario.start, waypoints,
                          movement_limits(params, params.movement.speed),
                          label_phases=False)
    return ScenarioPlan(plan)


#: s, longest simulator step while the tool slows down (ScenarioPlan.knots)
RAMP_STEP = 0.1


@dataclass(frozen=True)
class ScenarioPlan:
    """A ruckig :class:`~rheo_shaping.planning.plans.Plan` seen as a simulator tool path."""

    plan: Plan

    @property
    def duration(self) -> float:
        return float(self.plan.duration)

    def position(self, t: float) -> np.ndarray:
        return self.plan.sample(float(t))[0]

    def knots(self) -> np.ndarray:
        """Times [s] where the simulator must end a step.

        The starts and stops of every move, every ruckig jerk switch, and, inside
        each interval between switches where the tool slows down, steps of at
        most :data:`RAMP_STEP`. A tension peak comes while the tool slows down at
        the end of a move; with the process step alone (up to ``solver.dt`` and
        ``solver.max_tool_step``) a step could span the whole deceleration and
        sample the peak only at its ends: 0.9 % low at 2x the paper's speed
        (docs/model.md, Convergence). With these step ends F_max is within
        0.03 % of a 25 times finer step, for 10 % more steps.
        """
        ts = np.asarray(self.plan.knots(include_phases=True), dtype=float)
        ts = ts[(ts >= 0.0) & (ts <= self.duration)]
        extra = []
        if ts.size > 1:
            mid = 0.5 * (ts[:-1] + ts[1:])
            _, vel, acc = self.plan.sample_many(mid)
            slowing = np.einsum("ij,ij->i", vel, acc) < -1e-15     # speed falls: v . a < 0
            for a, b, ramp in zip(ts[:-1], ts[1:], slowing):
                if ramp and b - a > RAMP_STEP:
                    n = int(np.ceil((b - a) / RAMP_STEP))
                    extra.extend(a + (b - a) * np.arange(1, n) / n)
        return np.unique(np.concatenate([ts, np.asarray(extra, dtype=float)]))
