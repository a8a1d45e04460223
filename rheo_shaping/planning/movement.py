"""The one way to run a movement of a cell: plan it (ruckig) and simulate the sheet.

:func:`run_movement` replaces the chain ``run_scenario(p, scenario_plan(p,
movement_scenario(p)))``; :func:`movement_plan` is its plan alone.  No ROS here.
"""
from __future__ import annotations

import numpy as np

from ..params.cell import CellParams
from ..sheet.simulation import RunResult, run_scenario
from .plans import MotionLimits, Plan, Waypoint, plan_waypoints
from .scenarios import ScenarioPlan, movement_limits, movement_scenario, scenario_plan


def movement_plan(params: CellParams, number: int | None = None, *,
                  speed: float | None = None, dwell: float | None = None,
                  d: float | None = None) -> ScenarioPlan:
    """The jerk-limited plan of the paper's movement ``number`` (default
    ``movement.number``) with the cell's speed [m/s], dwell [s] and d [m] unless given."""
    return scenario_plan(params, movement_scenario(params, number, speed=speed, dwell=dwell,
                                                   d=d))


def run_movement(params: CellParams, number: int | None = None, *,
                 speed: float | None = None, dwell: float | None = None,
                 d: float | None = None, t_end: float | None = None) -> RunResult:
    """Simulate the cell over :func:`movement_plan` from t = 0 to ``t_end`` [s]
    (default ``movement.process_time``)."""
    plan = movement_plan(params, number, speed=speed, dwell=dwell, d=d)
    return run_scenario(params, plan, t_end=t_end)


def approach_plan(params: CellParams, plan: Plan, start_xz, approach: MotionLimits) -> Plan:
    """``plan`` (of the cell's movement), preceded by an approach from ``start_xz`` [m] at
    the ``approach`` limits when the tool is elsewhere (more than 1 um away)."""
    if start_xz is None or np.hypot(*(np.asarray(start_xz) - plan.start)) <= 1e-6:
        return plan
    scenario = movement_scenario(params)
    waypoints = [Waypoint(float(scenario.start[0]), float(scenario.start[1]), 0.0, "approach",
                          approach)]
    waypoints += [Waypoint(float(mv.target[0]), float(mv.target[1]), mv.dwell, mv.label,
                           movement_limits(params, mv.speed)) for mv in scenario.moves]
    return plan_waypoints(start_xz, waypoints, movement_limits(params, params.movement.speed),
                          label_phases=False)


def autostart_refusal(tool_xz, home_xz, start_xz, tolerance: float) -> str:
    """Why a plan must not start on its own: the tool at ``tool_xz`` [m] is neither at
    home nor at the plan's start (within ``tolerance`` [m]); "" when it may.

    A planner (re)started while the tool stands somewhere in a run must not run a plan
    from its beginning on its own (safety principle 3): it waits for ~/start, which
    plans an approach from where the tool is (:func:`approach_plan`).
    """
    tool = np.asarray(tool_xz, dtype=float)
    for where in (home_xz, start_xz):
        if np.hypot(*(tool - np.asarray(where, float))) <= tolerance:
            return ""
    x, z = tool
    return (f"the tool is at ({x:.4f}, {z:.4f}) m, neither at home nor at the plan's start "
            f"(start_tolerance {tolerance:g} m): no autostart; call ~/start to approach from "
            f"there")


def warm_up() -> float:
    """Load (or, on a user's first run, compile) every entry of the compiled step the nodes
    use, by running a short process of the default cell (cake, workplane and tool shapes,
    the settle, a scenario) once; returns the wall time it took [s].

    The node executables call it before ``rclpy.init``, so that loading the compiled code
    (numba calls back into Python through ctypes while it loads) and a long first compile
    happen while a signal can still end the process at once (:mod:`rheo_shaping.nodes.entry`).
    """
    import time
    from dataclasses import replace

    t0 = time.perf_counter()
    cell = CellParams()
    run_movement(replace(cell, movement=replace(cell.movement, process_time=5.0)))
    return time.perf_counter() - t0
