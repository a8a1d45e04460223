"""The offline optimum of a cell: the fastest rest of the movement (from t = 0, over the
re-planner's grid of stroke speeds and dwells) that meets both limits, computed knowing the
true cell (the campaign's yardstick for cycle time).  No ROS here.
"""
from __future__ import annotations

from dataclasses import replace

from ..params.cell import CellParams
from .estimator import Estimate, EstimateStatus
from .replan import Replan, ReplanLimits, replan
from .schedule import fixed_schedule


def truth(cell: CellParams) -> Estimate:
    """``cell``'s own material as an estimate without uncertainty."""
    return Estimate(t=0.0, status=EstimateStatus.OK, message="the true cell",
                    k1=cell.material.k1, c2=cell.material.c2,
                    mass_per_length=cell.sheet.mass_per_length,
                    cov=((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))


def offline_optimum(true_cell: CellParams, cell: CellParams, limits: ReplanLimits) -> Replan:
    """The fastest plan of the params file's movement (``cell``) that keeps the true cell
    ``true_cell`` under ``limits``, every candidate predicted on the true cell (friction
    and all); status REPLANNED or KEPT (the fixed plan is the fastest) when one exists,
    INFEASIBLE when none does."""
    exact = replace(limits, kappa=0.0, gap_margin=0.0, min_gain=0.0,
                    max_evaluations=10_000)
    return replan(true_cell, truth(true_cell), fixed_schedule(cell), 0.0, exact)
