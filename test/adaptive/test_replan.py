"""The re-plan (rheo_shaping.adaptive.join, schedule, replan): the new plan joins the running
one with equal position, velocity and acceleration, keeps the tool's limits, and an
infeasible cell is reported so with the plan that keeps the sheet whole."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.adaptive.settle import material_cell
from rheo_shaping.adaptive.join import ToolState
from rheo_shaping.adaptive.optimum import truth
from rheo_shaping.adaptive.replan import (GAP_CORNER, TENSION_CORNER, Prediction, ReplanLimits,
                                          ReplanStatus, replan)
from rheo_shaping.adaptive.schedule import Choice, fixed_schedule
from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import movement_plan, run_movement

NOMINAL = np.array([95.0, 1300.0, 0.3125])


def _cell(number: int) -> CellParams:
    c = CellParams()
    return replace(c, movement=replace(c.movement, number=number))


@pytest.mark.parametrize("number", [1, 4])
def test_the_fixed_schedule_is_the_params_files_plan(number):
    cell = _cell(number)
    sched, ref = fixed_schedule(cell), movement_plan(cell).plan
    t = np.linspace(0.0, ref.duration + 2.0, 4001)
    for a, b in zip(sched.plan.sample_many(t), ref.sample_many(t)):
        assert np.array_equal(a, b)
    assert sched.cycle_time == cell.movement.process_time
    assert len(sched.owners) == len(sched.plan.segments)


# t_join: accelerating (0.1 s), cruising (20 s), decelerating (35.6 s) in the first stroke,
# in the dwell (50 s); new speeds slower and faster than the running 1 mm/s
@pytest.mark.parametrize("t_join", [0.1, 20.0, 35.6, 50.0])
@pytest.mark.parametrize("speed", [0.5e-3, 3e-3])
def test_a_rejoin_has_no_jump_and_keeps_the_limits(t_join, speed):
    cell = _cell(1)
    old = fixed_schedule(cell)
    new = old.rejoin(t_join, Choice(speed, 0.5))
    assert new is not None
    before, after = ToolState.of(old.plan, t_join), ToolState.of(new.plan, t_join)
    for x, y in zip(before.arrays(), after.arrays()):      # set-point, velocity, acceleration
        assert np.max(np.abs(x - y)) <= 1e-12
    t = np.linspace(0.0, t_join, 2001)                      # the past is not rewritten
    assert np.array_equal(old.plan.sample_many(t)[0], new.plan.sample_many(t)[0])
    mv = cell.movement
    tt = np.linspace(t_join, new.plan.duration, 200_001)
    _, vel, acc = new.plan.sample_many(tt)
    v, a = np.hypot(*vel.T), np.hypot(*acc.T)
    v_join = float(np.hypot(*before.velocity))
    retract = max(mv.retract_speed, mv.retract_speed * speed / mv.speed)   # never slower
    assert v.max() <= max(v_join, speed, retract) * (1 + 1e-9)
    assert a.max() <= mv.accel * (1 + 1e-9)
    jerk = np.hypot(*(np.diff(acc, axis=0) / np.diff(tt)[:, None]).T)
    assert jerk.max() <= mv.jerk * (1 + 1e-6)
    assert np.all(np.abs(np.diff(a)) <= mv.jerk * np.diff(tt) * (1 + 1e-6))   # a continuous
    assert v.max() <= 0.05                                   # the simulator's max_tool_speed
    home = new.plan.sample(new.plan.duration)[0] - mv.start_1
    assert np.max(np.abs(home)) <= 1e-15                     # back at the start (round-off)


def test_a_rejoin_after_the_forced_strokes_is_none():
    sched = fixed_schedule(_cell(1))
    assert sched.rejoin(80.0, Choice(2e-3)) is None         # retracting


@pytest.mark.parametrize("number", [1, 4])
def test_the_corners_are_where_each_limit_is_worst(number):
    """F_max rises with k1, c2 and the mass; Delta rises with c2 and falls with k1 and the
    mass: the signs TENSION_CORNER and GAP_CORNER take (10 % steps)."""
    cell = _cell(number)
    r0 = run_movement(cell)
    for i in range(3):
        k = NOMINAL.copy()
        k[i] *= 1.1
        r = run_movement(material_cell(cell, k))
        assert np.sign(r.F_max - r0.F_max) == TENSION_CORNER[i]
        assert np.sign(r.delta - r0.delta) == GAP_CORNER[i]


def test_knowing_the_truth_the_replan_meets_both_limits_faster():
    cell = _cell(1)
    soft = material_cell(cell, NOMINAL * [0.7, 0.7, 1.0])    # flows easily: room to speed up
    limits = ReplanLimits(F_limit=0.98)
    sched = fixed_schedule(cell)
    rp = replan(soft, truth(soft), sched, 10.0, limits, executed_xz=sched.plan.sample(10.0)[0])
    assert rp.status is ReplanStatus.REPLANNED, rp.message
    p = rp.prediction
    assert p is not None and p.F_max <= 0.98 and p.delta <= 5e-3
    assert rp.schedule.cycle_time < sched.cycle_time - limits.min_gain
    assert 1 < rp.evaluations <= len(limits.speeds) + len(limits.dwell_factors) + 1
    assert rp.cost_s > 0.0


def test_no_plan_meets_both_limits_reports_so_and_keeps_the_sheet_whole():
    cell = _cell(1)
    sched = fixed_schedule(cell)
    limits = ReplanLimits(F_limit=0.98, delta_max=1e-4)        # no gap that small
    rp = replan(cell, truth(cell), sched, 10.0, limits)
    assert rp.status is ReplanStatus.INFEASIBLE and rp.changed
    assert "no rest of the movement meets both limits" in rp.message
    assert rp.prediction is not None and rp.prediction.F_max <= 0.98        # whole
    stiff = material_cell(cell, NOMINAL * [1.3, 1.3, 1.0])
    hard = replan(stiff, truth(stiff), sched, 10.0, ReplanLimits(F_limit=0.2))
    assert hard.status is ReplanStatus.INFEASIBLE
    slowest = Choice(min(hard.schedule.cell.movement.speed, 0.5e-3), 1.5)
    assert hard.schedule.choice == slowest                    # the least tension there is


def test_a_bad_estimate_or_a_tool_off_its_setpoint_is_not_replanned():
    cell = _cell(1)
    sched = fixed_schedule(cell)
    bad = replace(truth(cell), status=truth(cell).status.__class__.DIVERGED, message="x")
    rp = replan(cell, bad, sched, 10.0, ReplanLimits(F_limit=0.98))
    assert rp.status is ReplanStatus.NO_ESTIMATE and rp.schedule is sched
    off = sched.plan.sample(10.0)[0] + [0.0, 2e-3]
    rp = replan(cell, truth(cell), sched, 10.0, ReplanLimits(F_limit=0.98), executed_xz=off)
    assert rp.status is ReplanStatus.NO_ESTIMATE and "2e-03 m" in rp.message.replace(
        "0.002", "2e-03")


@pytest.mark.parametrize("field, value", [("F_limit", 0.0), ("delta_max", math.nan),
                                          ("kappa", -1.0), ("speeds", ())])
def test_bad_limits_are_refused_with_the_name(field, value):
    with pytest.raises(ValueError, match=field):
        ReplanLimits(**{"F_limit": 0.9, field: value})


def test_the_gap_margin_is_kept_off_the_quality_limit():
    """A prediction within delta_max but inside the margin is not feasible; the loop's
    limits keep GAP_MARGIN off 5 mm, the offline optimum (the true cell, exact) none."""
    from rheo_shaping.adaptive.loop import GAP_MARGIN, replan_limits
    cell = CellParams()
    limits = replan_limits(cell, 0.1, 0.005)
    assert limits.gap_margin == GAP_MARGIN and limits.gap_limit == 5e-3 - GAP_MARGIN
    edge = Prediction(choice=Choice(1e-3, 1.0), F_max=0.5, delta=5e-3 - 0.5 * GAP_MARGIN,
                      cycle_time=100.0)
    assert edge.whole(limits) and not edge.feasible(limits)
    assert edge.feasible(replace(limits, gap_margin=0.0))
    with pytest.raises(ValueError, match="gap_margin"):
        ReplanLimits(F_limit=1.0, gap_margin=5e-3)
