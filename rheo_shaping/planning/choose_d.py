"""Choice of movement 4's distance d with the core model (paper Fig. 18).

The paper finds the maximum tension of the 2-step movement smallest at the d
where its two force peaks are equal (d = 14.5e-3 m on its cell).
:func:`best_d` runs the cell's movement 4 for each candidate d
(:func:`rheo_shaping.sheet.simulation.run_scenario` over the same ruckig plan the
planner streams) and picks the smallest predicted F_max among the runs whose
residual gap Delta stays within the quality limit.  No ROS imports here.
"""
from __future__ import annotations

import math
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from typing import Callable, Iterable, Sequence

import numpy as np

from ..parallel import executor_from_spec, run_tasks
from ..params.cell import CellParams
from ..params.validators import check_positive
from .movement import run_movement


@dataclass(frozen=True)
class DRun:
    """Movement 4 at one d: F_max [N] and Delta [m] (inf when the run failed)."""

    d: float
    F_max: float
    delta: float
    error: str = ""


@dataclass(frozen=True)
class DChoice:
    """The chosen d [m], its F_max [N] and Delta [m], and every run tried."""

    d: float
    F_max: float
    delta: float
    runs: tuple[DRun, ...]


def d_values(d_min: float, d_max: float, d_step: float) -> np.ndarray:
    """Candidates ``d_min, d_min + d_step, ...`` up to ``d_max`` [m] (both ends included)."""
    check_positive("d_step [m]", d_step)
    if d_max < d_min:
        raise ValueError(f"d_max = {d_max!r} m is below d_min = {d_min!r} m")
    n = int(math.floor((d_max - d_min) / d_step + 1e-9))
    return d_min + d_step * np.arange(n + 1)


def run_d(params: CellParams, d: float) -> DRun:
    """Movement 4 of ``params`` with distance ``d`` [m], run by the core."""
    p = replace(params, movement=replace(params.movement, number=4, d=float(d)))
    try:
        result = run_movement(p)
    except (RuntimeError, ValueError) as exc:   # the sheet solver or the planner gave up
        return DRun(float(d), math.inf, math.inf, f"{type(exc).__name__}: {exc}")
    return DRun(float(d), float(result.F_max), float(result.delta))


def best_d(params: CellParams, d_candidates: Iterable[float], delta_limit: float,
           workers: int = 1, progress: Callable[[int], None] | None = None,
           executor: Executor | None = None) -> DChoice:
    """The d [m] with the smallest F_max among runs with Delta <= ``delta_limit`` [m].

    The candidates run on ``executor`` when given (:mod:`rheo_shaping.parallel`), else on
    a local pool of ``workers`` processes (spawned when the caller has threads, so safe
    in a ROS node), or here when ``workers`` is 1.  ``progress(k)``: k more runs done.
    Raises ``ValueError`` when no candidate meets the limit.
    """
    ds: Sequence[float] = [float(d) for d in d_candidates]
    if not ds:
        raise ValueError("no d values to try")
    if executor is not None:
        runs = run_tasks(executor, run_d, params, ds, progress)
    else:
        with executor_from_spec(None, jobs=max(1, min(workers, len(ds)))) as pool:
            runs = run_tasks(pool, run_d, params, ds, progress)
    ok = [r for r in runs if math.isfinite(r.F_max) and r.delta <= delta_limit]
    if not ok:
        finite = [r for r in runs if math.isfinite(r.delta)]
        best = min(finite, key=lambda r: r.delta, default=None)
        hint = (f"; the smallest Delta is {best.delta:.4g} m at d = {best.d:.4g} m" if best
                else "; every run failed")
        raise ValueError(f"no d in [{min(ds):.4g}, {max(ds):.4g}] m keeps Delta <= "
                         f"{delta_limit:.4g} m{hint}")
    choice = min(ok, key=lambda r: (r.F_max, r.d))
    return DChoice(choice.d, choice.F_max, choice.delta, tuple(runs))
