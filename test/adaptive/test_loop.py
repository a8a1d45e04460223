"""The offline closed loop (rheo_shaping.adaptive.loop): the true cell as the simulator
node's core, the estimator and re-planner knowing only the params file."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.adaptive.estimator import EstimateStatus, EstimatorParams, material_cell
from rheo_shaping.adaptive.loop import LoopConfig, run_closed_loop
from rheo_shaping.adaptive.replan import ReplanStatus
from rheo_shaping.params.cell import CellParams

NOMINAL = np.array([95.0, 1300.0, 0.3125])


@pytest.fixture(scope="module")
def soft():
    """Movement 1 on a batch that flows easily (k1, c2 x0.7, mass x1.2): the fixed plan
    shapes it, slower than the material allows."""
    cell = replace(CellParams(), movement=replace(CellParams().movement, number=1))
    true = material_cell(cell, NOMINAL * [0.7, 0.7, 1.2])
    return cell, true, run_closed_loop(true, cell, LoopConfig(adaptive=False, seed=1))


def test_the_adaptive_loop_shapes_sooner_than_the_fixed_plan(soft):
    cell, true, fixed = soft
    r = run_closed_loop(true, cell, LoopConfig(adaptive=True, seed=1))
    assert fixed.shaped and fixed.cycle_time == cell.movement.process_time
    assert r.shaped and not r.aborted and not r.torn
    assert r.F_max < r.F_abort and r.delta <= 5e-3
    assert r.cycle_time < 0.8 * fixed.cycle_time
    times = np.array([e.t for e in r.events])
    assert times[0] <= 2.0 + 1e-9 and np.all(np.diff(times) <= 2.0 + 0.1 + 1e-9)
    assert any(e.replan is not None and e.replan.changed for e in r.events)
    final = r.events[-1].estimate                              # the truth, as it is known
    z = np.log(final.theta / (NOMINAL * [0.7, 0.7, 1.2])) / final.sigma_rel
    assert final.status is EstimateStatus.OK and np.all(np.abs(z) <= 3.0)
    # (a refresh's CPU cost is a figure: benchmarks/closed_loop_cost.py prints it)
    assert np.all(r.costs() > 0.0)


def test_a_bad_estimate_keeps_the_fixed_plan(soft):
    """An estimator that finds every fit diverged (chi^2/dof limit 1e-9): no re-plan acts on
    it, and the run is the fixed plan's."""
    cell, true, fixed = soft
    config = LoopConfig(adaptive=True, seed=1, estimator=EstimatorParams(max_chi2=1e-9))
    r = run_closed_loop(true, cell, config)
    assert all(e.replan is not None and e.replan.status is ReplanStatus.NO_ESTIMATE
               for e in r.events[1:])
    assert r.events[-1].estimate.status is EstimateStatus.DIVERGED
    assert r.cycle_time == fixed.cycle_time and r.F_max == fixed.F_max
    assert r.delta == fixed.delta
