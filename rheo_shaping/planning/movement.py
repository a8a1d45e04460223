"""The one way to run a movement of a cell: plan it (ruckig) and simulate the sheet.

:func:`run_movement` replaces the chain ``run_scenario(p, scenario_plan(p,
movement_scenario(p)))``; :func:`movement_plan` is its plan alone.  No ROS here.
"""
from __future__ import annotations

from ..params.params import CellParams
from ..sheet.simulation import RunResult, run_scenario
from .scenarios import ScenarioPlan, movement_scenario, scenario_plan


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
