"""The closed loop as the planner node runs it (rheo_shaping.adaptive.online): samples in,
a re-plan joined ahead of the stream, the streamer switching without a jump."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rheo_shaping.adaptive.settle import material_cell
from rheo_shaping.adaptive.observe import sample_of
from rheo_shaping.adaptive.online import OnlineConfig, OnlineShaper, Reason
from rheo_shaping.adaptive.schedule import Choice, fixed_schedule
from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.stopping import TrajectoryStreamer
from rheo_shaping.sheet.setpoints import SetpointRun
from rheo_shaping.units import NS

NOMINAL = np.array([95.0, 1300.0, 0.3125])
DT = 0.1                                   # s, the control period of this loop


def movement_1() -> CellParams:
    return replace(CellParams(), movement=replace(CellParams().movement, number=1))


def test_the_streamed_run_re_plans_ahead_of_the_stream_and_shapes_sooner():
    """Movement 1 on a batch that flows easily (k1, c2 x0.7, mass x1.2), streamed as the
    planner node streams it: the re-plans join after what was already sent, the set-points
    never jump, the true cell is shaped well before the params file's process time."""
    cell = movement_1()
    true = material_cell(cell, NOMINAL * [0.7, 0.7, 1.2])
    true = replace(true, movement=replace(true.movement, process_time=600.0))
    shaper = OnlineShaper(cell, OnlineConfig(join_lead=0.5))
    streamer = TrajectoryStreamer()
    streamer.start(shaper.plan, 0.0)
    run = SetpointRun(true, tool_start=shaper.plan.start)
    run.command(0, *shaper.plan.start)
    sent = [np.asarray(shaper.plan.start)]
    t, switched = 0.0, 0
    while t < shaper.schedule.cycle_time - 1e-9 and not run.broken:
        t = round(t + DT, 9)
        p = streamer.setpoint(t)[0]
        sent.append(p)
        run.command(round(t * NS), float(p[0]), float(p[1]))
        run.advance(round(t * NS))
        if shaper.wants(t):
            assert shaper.add(sample_of(run.sim))
        reason = shaper.due(t)
        if reason is not None:
            step = shaper.refresh(t, reason, executed_xz=tuple(run.sim.state.tool))
            assert step.t_join == pytest.approx(t + 0.5)
            if step.plan is not None:
                streamer.replace_rest(step.plan, step.t_join)
                shaper.accept(step)
                switched += 1
    steps = np.linalg.norm(np.diff(np.array(sent), axis=0), axis=1)
    v_max = max(*shaper.limits.speeds, cell.movement.retract_speed)     # path speed [m/s]
    assert switched >= 1 and not run.broken
    assert steps.max() <= v_max * DT + 1e-9                   # no jump at any join
    assert max(f for _, f in run.history) < shaper.limits.F_limit
    assert run.sim.delta() <= 5e-3
    assert shaper.schedule.cycle_time < 0.8 * cell.movement.process_time
    reasons = {s.reason for s in shaper.steps}
    assert reasons == {Reason.PERIOD, Reason.BOUNDARY}


def test_a_join_already_streamed_or_off_the_running_plan_is_refused():
    cell = movement_1()
    sched = fixed_schedule(cell)
    streamer = TrajectoryStreamer()
    streamer.start(sched.plan, 10.0)
    streamer.setpoint(10.0 + 20.0)                            # streamed to plan time 20 s
    faster = sched.rejoin(25.0, Choice(2 * cell.movement.speed))
    assert faster is not None
    with pytest.raises(ValueError, match="already streamed"):
        streamer.replace_rest(faster.plan, 20.0)
    other = fixed_schedule(cell, Choice(2 * cell.movement.speed)).plan
    with pytest.raises(ValueError, match="position"):
        streamer.replace_rest(other, 25.0)
    streamer.replace_rest(faster.plan, 25.0)
    assert streamer.plan is faster.plan
    streamer.abort(10.0 + 21.0)
    with pytest.raises(RuntimeError, match="running"):
        streamer.replace_rest(faster.plan, 40.0)


def test_the_samples_are_kept_one_per_period_and_a_refresh_is_due_on_time():
    shaper = OnlineShaper(movement_1(), OnlineConfig(sample_period=0.5, refresh_period=2.0))
    run = SetpointRun(movement_1(), tool_start=shaper.plan.start)
    kept = [shaper.add(replace(sample_of(run.sim), t=t)) for t in (0.0, 0.2, 0.5, 0.9, 1.0)]
    assert kept == [True, False, True, False, True]
    assert shaper.due(1.9) is None and shaper.due(2.0) is Reason.PERIOD


def test_the_worker_process_refreshes_as_the_shaper_in_this_process_does():
    """ShaperProcess: the same samples give the same step in its worker process as in an
    OnlineShaper here, and an accepted step is the worker's schedule at the next refresh."""
    from rheo_shaping.adaptive.worker import ShaperProcess
    cell = movement_1()
    true = material_cell(cell, NOMINAL * [0.7, 0.7, 1.2])
    here = OnlineShaper(cell)
    run = SetpointRun(true, tool_start=here.plan.start)
    samples = []
    for k in range(1, 41):                                     # 4 s, a sample every 0.5 s
        t = k * DT
        p = here.plan.sample(t)[0]
        run.command(round(t * NS), float(p[0]), float(p[1]))
        run.advance(round(t * NS))
        if k % 5 == 0:
            samples.append(sample_of(run.sim))
    proc = ShaperProcess(cell)
    try:
        proc.start(cell, OnlineConfig())
        index, step, cpu = proc.submit(samples, 4.0, Reason.PERIOD, None, 4.0, 0.0).result(120)
        for s in samples:
            here.add(s)
        mine = here.refresh(4.0, Reason.PERIOD, None, streamed=4.0)
        assert index == 0 and cpu > 0.0
        assert step.estimate.k1 == mine.estimate.k1 and step.message == mine.message
        # (the prior's spread at 4 s: the fixed plan's pessimistic tension is over the
        # limit, a slower rest is chosen)
        assert step.plan is not None and mine.plan is not None
        if step.plan is not None:
            proc.accept(index, step)
            assert proc.shaper is not None and proc.shaper.plan is step.plan
            _, again, _ = proc.submit([], 6.0, Reason.PERIOD, None, 6.0, 0.0).result(120)
            # the worker follows the accepted plan: before the new join (7 s) its schedule is
            # the step's, which left the params file's plan at 5 s
            fixed = OnlineShaper(cell).plan
            assert not np.allclose(step.plan.sample(6.5)[0], fixed.sample(6.5)[0], atol=1e-9)
            assert np.allclose(again.schedule.plan.sample(6.5)[0], step.plan.sample(6.5)[0],
                               atol=1e-12)
    finally:
        proc.close()


def test_the_streamed_loop_samples_submits_and_switches_at_the_next_tick():
    """The planner node's closed loop (rheo_shaping.adaptive.streamed.StreamedLoop) on a
    real worker process, driven as the node drives it: a sample per period at the executed
    poses, a refresh submitted when due and taken at a later control tick, the stream
    switched at the join without a jump; a result whose join was already streamed is
    dropped with the reason."""
    from rheo_shaping.adaptive.streamed import StreamedLoop
    from rheo_shaping.adaptive.worker import ShaperProcess
    from rheo_shaping.planning.run_state import SetpointGrid
    cell = movement_1()
    true = material_cell(cell, NOMINAL * [0.7, 0.7, 1.2])
    proc = ShaperProcess(cell)
    try:
        online = proc.start(cell, OnlineConfig(join_lead=0.5))
        clock = {"t": 0.0}                    # a cell at real time: the wall is its clock
        loop = StreamedLoop(online, proc, monotonic=lambda: clock["t"])
        streamer = TrajectoryStreamer()
        streamer.start(online.plan, 0.0)
        grid = SetpointGrid(0, round(DT * NS))
        run = SetpointRun(true, tool_start=online.plan.start)
        sent, taken = [np.asarray(online.plan.start)], []
        t = 0.0
        while t < 12.0 and not any(r.switched for r in taken):
            t = clock["t"] = round(t + DT, 9)
            for t_ns in grid.due(round(t * NS), round(t * NS), sim_time=False):
                p = streamer.setpoint(t_ns / NS)[0]
                sent.append(p)
                run.command(t_ns, float(p[0]), float(p[1]))
            run.advance(round(t * NS))
            sample = sample_of(run.sim)
            loop.pose(run.sim.state.tool, round(t * NS), 0, sample.wrench,
                      sample.contact_tension)
            if loop.work is not None:
                loop.work.result(120)         # the worker's refresh, waited for here
            r = loop.tick(streamer, grid, round(t * NS), run.sim.state.tool)
            if r is not None:
                taken.append(r)
        assert taken and taken[-1].switched, [r.note for r in taken]
        r = taken[-1]
        assert r.note.startswith(f"re-planned from t = {r.step.t_join:.2f} s")
        assert r.data["switched"] and r.data["worker_cpu_s"] > 0.0
        assert streamer.plan is r.step.plan
        steps = np.linalg.norm(np.diff(np.array(sent), axis=0), axis=1)
        v_max = max(*online.limits.speeds, cell.movement.retract_speed)
        assert steps.max() <= v_max * DT + 1e-9                   # no jump at the join
        # the same result again, once the stream has passed its join: dropped, named
        streamer.setpoint(r.step.t_join + 1.0)
        again = loop.take(99, r.step, streamer)
        assert not again.switched and again.warning
        assert again.note.startswith("re-plan dropped (")
        # what /diagnostics says of each: WARN when no rest meets both limits (the one that
        # keeps the sheet whole runs: with the prior's spread at 2 s, here), or dropped
        level, message, values = r.status()
        assert message.startswith("re-planned from t = ")
        assert level == ("WARN" if values["replan"] in ("infeasible", "no_estimate") else "OK")
        assert values["switched"] and values["k1 [N/m]"] == r.step.estimate.k1
        assert values["estimate"] == r.step.estimate.status.value
        assert again.status()[0] == "WARN" and not again.status()[2]["switched"]
    finally:
        proc.close()


def test_a_re_plan_joins_after_what_a_refresh_streams_at_the_cells_pace():
    """A cell faster than real time streams seconds of process time while one refresh
    computes: the join is twice the larger of the last refresh's span and the next one's
    wall time at the cell's pace (the first refresh before any is measured: 0.5 s)."""
    from rheo_shaping.adaptive.streamed import FIRST_REFRESH_S, join_lead
    assert join_lead(0.0, 1.0, FIRST_REFRESH_S) == 1.0            # x1: the config's 1 s
    assert join_lead(0.0, 20.0, FIRST_REFRESH_S) == 20.0          # x20: 10 s a refresh
    assert join_lead(6.0, 20.0, 0.2) == 12.0                      # the span measured
    assert join_lead(3.0, 20.0, 0.3) == 12.0                      # the pace x wall


def test_a_paced_loop_holds_the_stream_at_the_join_until_its_re_plan_comes():
    """A simulated cell at x20 whose refresh takes 0.3 s of wall time (6 s of its process
    time): paced, the stream sends nothing at or beyond the running refresh's join (the
    simulator, in lockstep, waits), so every re-plan joins exactly ``join_lead`` after what
    was streamed and none is dropped; the cap goes once the re-plan is taken."""
    from rheo_shaping.adaptive.streamed import StreamedLoop
    from rheo_shaping.adaptive.worker import ShaperProcess
    from rheo_shaping.planning.run_state import SetpointGrid

    class Late:                           # the worker's future, seen done 0.3 s wall later
        def __init__(self, fut, ready_at: float):
            self.fut, self.ready_at = fut, ready_at

        def done(self) -> bool:
            return clock["t"] >= self.ready_at and self.fut.done()

        def result(self, timeout=None):
            return self.fut.result(timeout)

    cell = movement_1()
    true = material_cell(cell, NOMINAL * [0.7, 0.7, 1.2])
    proc = ShaperProcess(cell)
    try:
        online = proc.start(cell, OnlineConfig(join_lead=0.5))
        clock = {"t": 0.0}                    # the wall [s]; the cell runs at x20 of it
        loop = StreamedLoop(online, proc, monotonic=lambda: clock["t"], paced=True)
        streamer = TrajectoryStreamer()
        streamer.start(online.plan, 0.0)
        grid = SetpointGrid(0, round(DT * NS))
        run = SetpointRun(true, tool_start=online.plan.start)
        taken, began, waits, seen_done, t = [], [], 0, 0, 0.0
        while t < 10.0:
            target = round((t + DT) * NS)
            cap = loop.limit_ns(streamer.state)
            for t_ns in grid.due(target, target if cap is None else min(target, cap),
                                 sim_time=False):
                assert cap is None or t_ns <= cap
                p = streamer.setpoint(t_ns / NS)[0]
                run.command(t_ns, float(p[0]), float(p[1]))
            if grid.last_ns is not None and grid.last_ns >= target:    # lockstep: a step
                t = round(t + DT, 9)
                clock["t"] += DT / 20.0
                run.advance(target)
                sample = sample_of(run.sim)
                loop.pose(run.sim.state.tool, target, 0, sample.wrench,
                          sample.contact_tension)
            else:                                                   # waits for the loop
                waits += 1
                loop.work.fut.result(120)     # the worker's real time is not this wall's
                clock["t"] += 0.05
                assert loop.work is not None and cap is not None
                seen_done += loop.serve_now()           # the node takes it on the wall
            had = loop.work
            r = loop.tick(streamer, grid, round(t * NS), run.sim.state.tool)
            if loop.work is not None and loop.work is not had:     # a refresh submitted
                began.append(loop.began)
                loop.work = Late(loop.work, clock["t"] + 0.3)
            if r is not None:
                taken.append(r)
                assert loop.limit_ns(streamer.state) is None or loop.work is not None
        replans = [r for r in taken if r.step.plan is not None]
        assert len(replans) >= 2 and waits > 0 and seen_done > 0
        assert all(r.switched for r in replans), [r.note for r in replans]
        assert loop.limit_ns("stopping") is None   # a stop never waits for a refresh
        # a refresh slower than PACE_WAIT_S is not waited for: the stream goes on
        from rheo_shaping.adaptive.streamed import PACE_WAIT_S
        loop.cap_ns, loop.work, loop._submitted = 10 * NS, Late(loop.work, 1e9), clock["t"]
        assert loop.limit_ns("running") == 10 * NS and not loop.serve_now()
        clock["t"] += PACE_WAIT_S + 0.01
        assert loop.limit_ns("running") is None and loop.serve_now()
        for r in taken:                    # the join: what was streamed + join_lead
            joins = [b + 0.5 for b in began]
            assert any(abs(j - r.step.t_join) < 1e-9 for j in joins), (r.step.t_join, joins)
    finally:
        proc.close()
