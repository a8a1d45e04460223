"""The one way to run a movement of a cell: plan it (ruckig) and simulate the sheet.

:func:`run_movement` replaces the chain ``run_scenario(p, scenario_plan(p,
movement_scenario(p)))``; :func:`movement_plan` is its plan alone.  No ROS here.
"""
from __future__ import annotations

import numpy as np

from ..params.cell import CellParams
from ..records.measurement import MeasurementParams, measure
from ..records.record import Record
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


def synthesize_record(params: CellParams, measurement: MeasurementParams = MeasurementParams(),
                      seed: int | None = None, name: str = "") -> tuple[Record, RunResult]:
    """A stand-in record of the cell of ``params``: its movement planned, run (effects on as
    set) and measured (:mod:`rheo_shaping.records.measurement`); returns the record and the
    true run."""
    path = movement_plan(params)
    run = run_scenario(params, path)
    rng = np.random.default_rng(seed)
    return measure(run, path, params, measurement, rng, name), run
