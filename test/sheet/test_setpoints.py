"""The simulator node's core without ROS: rheo_shaping.sheet.setpoints.SetpointRun."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.movement import movement_plan
from rheo_shaping.sheet.metrics import safety_factor
from rheo_shaping.sheet.setpoints import SetpointRun
from rheo_shaping.units import NS

T0 = 7 * NS                     # node time of the first set-point [ns]


@pytest.fixture(scope="module")
def cell() -> CellParams:
    c = CellParams()
    return replace(c, sheet=replace(c.sheet, n_masses=15),
                   movement=replace(c.movement, process_time=3.0))


def test_buffer_interpolates_between_stamps_then_holds(cell):
    run = SetpointRun(cell, (0.05, 0.10))
    assert not run.started
    assert np.array_equal(run.tool_at(T0), run.sim.state.tool)          # nothing yet
    assert run.command(T0, 0.05, 0.10)                                   # starts the process
    assert run.started and run.offset_ns == T0
    assert np.array_equal(run.sim.state.tool, [0.05, 0.10])
    assert not run.command(T0 + NS, 0.07, 0.06)
    assert run.tool_at(T0 + NS // 4) == pytest.approx([0.055, 0.09], abs=1e-15)
    assert run.tool_at(T0 - NS) == pytest.approx([0.05, 0.10])           # before: the first
    assert run.tool_at(T0 + 5 * NS) == pytest.approx([0.07, 0.06])       # after: hold
    assert run.lacks_setpoint(T0 + NS + 1) and not run.lacks_setpoint(T0 + NS)


def test_newest_set_point_for_a_time_replaces_what_followed(cell):
    run = SetpointRun(cell, (0.05, 0.10))
    for k, z in enumerate((0.10, 0.09, 0.08, 0.07)):
        run.command(T0 + k * NS, 0.05, z)
    run.command(T0 + NS, 0.06, 0.095)                                     # re-planned
    assert [c[0] for c in run.cmds] == [T0, T0 + NS]
    assert run.tool_at(T0 + NS) == pytest.approx([0.06, 0.095])
    run.prune(T0 + NS + 1)                                                # keeps the one before
    assert [c[0] for c in run.cmds] == [T0 + NS]


def test_start_without_a_set_point(cell):
    run = SetpointRun(cell, (0.05, 0.10))
    run.start_at(T0)
    assert run.started and run.history == [(0.0, pytest.approx(float(np.max(
        run.sim.state.tension))))]


def streamed_movement_1(cell, seconds: float) -> SetpointRun:
    """A run of movement 1 with its set-points of ``seconds`` [s] buffered every 0.05 s."""
    plan = movement_plan(cell, 1)
    run = SetpointRun(cell, plan.position(0.0))
    for t in np.arange(0.0, seconds, 0.05):
        x, z = plan.position(t)
        run.command(T0 + int(round(t * NS)), float(x), float(z))
    return run


def test_process_end_summary_and_peak_stop_at_process_time(cell):
    run = streamed_movement_1(cell, 6.0)
    assert run.advance(T0 + 2 * NS) is None and run.summary is None
    assert run.process_time == pytest.approx(2.0)
    so_far = run.summary_so_far()
    assert so_far.F_max == run.peak.value and so_far.delta == run.sim.delta()
    pt = run.advance(T0 + 5 * NS)                       # crosses process_time 3 s: stops there
    assert pt == 3.0 and run.process_time == pytest.approx(3.0)
    s = run.summary
    in_process = [f for t, f in run.history if t <= 3.0 + 1e-9]
    assert s.F_max == max(in_process) and s.F_max_time <= 3.0
    assert s.SF == safety_factor(cell.material.F_break, s.F_max)
    assert s.delta == run.sim.delta()
    assert run.advance(T0 + 5 * NS) is None             # goes on; the summary stays
    assert run.process_time == pytest.approx(5.0) and run.summary is s
    assert run.peak.value == s.F_max                     # later steps do not count
    assert run.history[-1][0] == pytest.approx(5.0)


def test_a_process_ended_later_is_judged_at_its_new_end(cell):
    """end_at (a re-planned cycle): the summary comes at the newest end asked before it was
    reached (a later one, then an earlier one: each re-plan moves it), with the peak over
    the whole of it and the gap there; never before the cell's own end, and no change once
    the end was reached or for a time already passed."""
    run = streamed_movement_1(cell, 6.0)
    run.advance(T0 + 2 * NS)
    run.end_at(2.5)                                      # before the cell's 3 s: 3 s
    assert run.cell.movement.process_time == 3.0
    run.end_at(4.5)
    run.end_at(1.0)                                      # passed: no change
    assert run.cell.movement.process_time == 4.5
    run.end_at(4.0)                                      # a shorter re-plan, not yet reached
    assert run.advance(T0 + 5 * NS) == 4.0 and run.process_time == pytest.approx(4.0)
    s = run.summary
    assert s.F_max == max(f for t, f in run.history if t <= 4.0 + 1e-9)
    assert s.delta == run.sim.delta()
    run.end_at(5.0)                                      # ended: stays at 4 s
    assert run.cell.movement.process_time == 4.0 and run.summary is s


def test_a_cycle_ends_at_its_plan_end_plus_the_params_files_settle():
    from rheo_shaping.adaptive.schedule import cycle_end, fixed_schedule
    cell = CellParams()
    nominal = movement_plan(cell).duration
    assert cycle_end(120.0, nominal, nominal) == 120.0           # the fixed plan
    assert cycle_end(120.0, nominal, nominal - 10.0) == 120.0    # shorter: judged at 120 s
    assert cycle_end(120.0, nominal, nominal + 7.0) == pytest.approx(127.0)
    assert cycle_end(120.0, 130.0, 131.0) == 131.0               # no settle left
    sched = fixed_schedule(cell)                                 # Schedule.cycle_time's rule
    assert sched.cycle_time == pytest.approx(cycle_end(120.0, nominal, sched.plan.duration))


def test_a_failed_solver_publishes_nan(cell):
    run = SetpointRun(cell, (0.05, 0.10))
    run.broken = "ConvergenceError: test"
    assert np.isnan(run.tensions()).all()
    run.command(T0, 0.05, 0.10)
    assert run.advance(T0 + NS) is None and run.process_time == 0.0


def test_a_step_starts_the_process_and_a_step_past_its_end_gives_the_end_first(cell):
    """The simulator's step: without start_on_command the process starts with the first
    step; a step that crosses process_time returns the end's node time (its state is the
    one published), and advancing again goes on to the target."""
    run = SetpointRun(cell, (0.05, 0.10))
    assert run.step_to(T0, start_on_command=True) == (None, None) and not run.started
    assert run.step_to(T0, start_on_command=False) == (None, None)
    assert run.started and run.offset_ns == T0
    assert run.step_to(T0 + 2 * NS, start_on_command=False) == (None, None)
    finished, end_ns = run.step_to(T0 + 4 * NS, start_on_command=False)
    assert finished == 3.0 and end_ns == T0 + 3 * NS
    assert run.process_time == pytest.approx(3.0) and run.summary is not None
    assert run.advance(T0 + 4 * NS) is None and run.process_time == pytest.approx(4.0)
    # a step that ends exactly at the process end: no earlier state to publish
    exact = SetpointRun(cell, (0.05, 0.10))
    exact.step_to(T0, start_on_command=False)
    assert exact.step_to(T0 + 3 * NS, start_on_command=False) == (3.0, None)


def test_a_hold_drops_every_buffered_setpoint_for_the_tools_position(cell):
    run = streamed_movement_1(cell, 3.0)
    run.advance(T0 + NS)
    here = run.sim.state.tool.copy()
    assert np.array_equal(run.hold(T0 + NS), here)
    assert run.cmds == [(T0 + NS, float(here[0]), float(here[1]))]
    run.advance(T0 + 2 * NS)
    assert np.array_equal(run.sim.state.tool, here)              # it stays there


def test_the_simulated_clock_steps_holds_and_waits_as_its_policy_says():
    """SimClock: /clock one step ahead of a step; held at the next step's time for the first
    set-point, the state re-published every HOLD_REPUBLISH s of steady time; a wait keeps
    the step due; each choice counted."""
    from rheo_shaping.sheet.setpoints import (HOLD_FOR_START, HOLD_REPUBLISH, LATE_STEP, STEP,
                                              WAIT_MONITOR, WAIT_SETPOINT, SimClock)
    c = SimClock(NS // 50)
    tick = c.tick(STEP, 0)
    assert (tick.step_to, tick.clock_ns) == (NS // 50, NS // 25)
    assert not tick.wait and not tick.late
    c.t_ns = tick.step_to                              # the node stepped there
    hold_ns = round(HOLD_REPUBLISH * NS)
    held = [c.tick(HOLD_FOR_START, s) for s in (0, NS // 20, hold_ns, hold_ns + 1)]
    assert all(t.step_to is None and t.clock_ns == 2 * NS // 50 for t in held)
    assert [t.republish for t in held] == [True, False, True, False]
    assert c.clock_holds == 4
    assert c.tick(WAIT_MONITOR, 0).wait and c.waits == 0           # the monitor's own count
    assert c.tick(WAIT_SETPOINT, 0).wait and c.waits == 1
    late = c.tick(LATE_STEP, 0)
    assert late.late and late.step_to == 2 * NS // 50 and c.late_steps == 1
    assert SimClock(0).dt_ns == 1                      # never a step of zero


def test_the_step_policy_in_its_order():
    """Every branch of the simulator's step policy on simulated time; the monitor's count of
    waits is asked only once the start is not held."""
    from rheo_shaping.sheet.setpoints import (HOLD_FOR_START, LATE_STEP, STEP, WAIT_MONITOR,
                                              WAIT_SETPOINT, next_step)
    asked = []

    def behind(value):
        return lambda: asked.append("monitor") or value

    yes, no = (lambda: True), (lambda: False)
    # before the first set-point, lockstep and start_on_command: /clock holds
    assert next_step(True, True, False, True, behind(True), yes, False, yes) == HOLD_FOR_START
    assert asked == []
    # the first step of the clock is taken (t = 0), and without start_on_command it runs
    assert next_step(True, True, False, False, behind(False), no, False, yes) == STEP
    assert next_step(True, False, False, True, behind(False), no, False, yes) == STEP
    assert next_step(True, True, True, True, behind(True), yes, False, yes) == WAIT_MONITOR
    assert next_step(True, True, True, True, behind(False), yes, False, yes) == WAIT_SETPOINT
    # the stream went quiet (command_timeout), or no lockstep: step without the set-point
    assert next_step(True, True, True, True, behind(False), yes, False, no) == LATE_STEP
    assert next_step(False, True, True, True, behind(False), yes, False, yes) == LATE_STEP
    # a held tool steps on (it holds where it is; no set-point is waited for)
    assert next_step(True, True, True, True, behind(False), yes, True, yes) == STEP


def test_the_run_status_names_the_worst_first():
    from rheo_shaping.sheet.setpoints import run_status
    assert run_status("diverged", "abort", True, False, 3.0, 120.0) == (
        "ERROR", "sheet solver failed: diverged")
    assert run_status("", "abort: x", True, False, 3.0, 120.0) == (
        "ERROR", "the tool holds: abort: x")
    assert run_status("", "", False, False, 0.0, 120.0)[1].startswith("waiting for the first")
    assert run_status("", "", True, False, 3.04, 120.0) == ("OK", "process time 3.0 s")
    assert run_status("", "", True, True, 120.0, 120.0) == ("OK", "process done at 120 s")
