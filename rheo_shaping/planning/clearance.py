"""Room for the sheet between the tool and the mould along a plan.

A tool that comes closer to the cake or the workplane than the sheet is thick
pinches the sheet: the model's tension then jumps by newtons within one step
(benchmarks/abort_campaign.py), far faster than any tension monitor can stop
the tool.  :func:`plan_clearance` finds the smallest gap between the tool's
cross-section and the mould (cake and workplane) along a plan, so the planner
can refuse such a plan before it moves.  No ROS imports here.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..sheet.geometry import Cake, Workplane
from ..params.cell import CellParams
from ..params.schema import ParameterError
from .plans import Plan
from ..sheet.tools import tool_shape


@dataclass(frozen=True)
class Clearance:
    """Smallest gap [m] between tool and mould, where the tool was (x, z) [m], when [s], and
    what."""

    gap: float
    at: tuple[float, float]
    time: float
    obstacle: str


def plan_clearance(params: CellParams, plan: Plan, step: float = 2e-4,
                   n_outline: int = 96) -> Clearance:
    """The smallest tool-to-mould gap along ``plan`` (sampled every ``step`` [m] of travel or
    less)."""
    v = max(plan.max_speed, 1e-12)
    dt = min(step / v, max(plan.duration, 1e-9))
    times = np.unique(np.concatenate(
        [np.arange(0.0, plan.duration, dt), plan.knots(), [plan.duration]]))
    pos, _, _ = plan.sample_many(times)
    outline = tool_shape(params.tool).outline(n_outline)               # (K, 2) about the reference
    pts = (pos[:, None, :] + outline[None, :, :]).reshape(-1, 2)
    c = params.cake
    nearest = []                                    # the nearest approach to each shape
    for name, shape in (("cake", Cake.of(c)),
                        ("workplane", Workplane())):
        d, _ = shape.signed_distance(pts)
        d = d.reshape(len(times), -1).min(axis=1)
        k = int(np.argmin(d))
        nearest.append(Clearance(float(d[k]), (float(pos[k, 0]), float(pos[k, 1])),
                                 float(times[k]), name))
    return min(nearest, key=lambda cl: cl.gap)     # on a tie the first (the cake)


def require_clearance(cell: CellParams, plan: Plan, factor: float) -> None:
    """Refuse (:class:`ParameterError`) a plan that leaves less room than ``factor`` x the
    sheet's thickness between tool and mould; ``factor`` 0 disables the check."""
    if factor <= 0:
        return
    need = factor * cell.sheet.thickness
    cl = plan_clearance(cell, plan)
    if cl.gap < need - 1e-6:
        raise ParameterError(
            f"the plan brings the tool within {cl.gap * 1e3:.2f} mm of the {cl.obstacle} at "
            f"({cl.at[0] * 1e3:.2f}, {cl.at[1] * 1e3:.2f}) mm, t = {cl.time:.1f} s: less than "
            f"clearance_factor {factor:g} x sheet.thickness {cell.sheet.thickness * 1e3:g} mm "
            f"pinches the sheet (parameter 'clearance_factor' = 0 disables the check)")
