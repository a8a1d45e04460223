"""The closed loop against the dynamic world (:mod:`rheo_shaping_validation.worlds`): another model
form than the estimator's and re-planner's sheet (inertia, soft contact, the sheet laid and
released at t = 0), to show the estimate survives a model-form gap.

The world cannot be stepped from outside, but it is causal: its run up to t depends on the
tool path up to t only.  So the world runs over the whole plan in force; the samples up to a
refresh are read from that run, and a re-plan that changes the rest of the plan runs the
world again over the spliced plan (identical up to the join).  The monitor's decision is
taken on the world's largest link tension; after an abort the world runs over the plan
stopped there (ruckig, jerk-limited).  No ROS here.
"""
from __future__ import annotations

import math

import numpy as np

from rheo_shaping.params.cell import CellParams
from rheo_shaping.planning.scenarios import ScenarioPlan
from rheo_shaping.planning.stopping import stop_from_state
from rheo_shaping.sheet.metrics import residual_gap
from rheo_shaping_validation.worlds import LayParams, WorldNumerics, WorldRun, run_world
from rheo_shaping.adaptive.estimator import Estimator
from rheo_shaping.adaptive.join import splice
from rheo_shaping.adaptive.loop import (LoopConfig, LoopEvent, LoopResult, monitor_threshold,
                                        replan_limits)
from rheo_shaping.adaptive.observe import Sample, noisy
from rheo_shaping.adaptive.replan import ReplanLimits, ReplanStatus, replan
from rheo_shaping.adaptive.schedule import Schedule, fixed_schedule


def _world(true_cell: CellParams, sched: Schedule, lay: LayParams,
           numerics: WorldNumerics) -> WorldRun:
    return run_world(true_cell, ScenarioPlan(sched.plan), t_end=sched.cycle_time, lay=lay,
                     numerics=numerics)


def _sample(world: WorldRun, k: int) -> Sample:
    """The world's sample k: tool, wrench and the gap of its profile (no contact tension:
    the world does not report which links touch the tool)."""
    gap = residual_gap(world.nodes(k), world.params.sheet.thickness)
    return Sample(t=float(world.t[k]), tool=(float(world.tool[k, 0]), float(world.tool[k, 1])),
                  wrench=(float(world.tool_force[k, 0]), float(world.tool_force[k, 1])),
                  contact_tension=None, gap=gap if math.isfinite(gap) else None)


def run_world_loop(true_cell: CellParams, cell: CellParams, config: LoopConfig = LoopConfig(),
                   limits: ReplanLimits | None = None, lay: LayParams = LayParams(),
                   numerics: WorldNumerics = WorldNumerics()) -> LoopResult:
    """:func:`~.loop.run_closed_loop` with the dynamic world as the true cell."""
    limits = (replan_limits(cell, config.detect_time, config.noise_sigma)
              if limits is None else limits)
    F_abort = monitor_threshold(cell, config.detect_time, config.noise_sigma)
    rng = np.random.default_rng(config.seed)
    sched = fixed_schedule(cell)
    fixed_choice = sched.choice
    world = _world(true_cell, sched, lay, numerics)
    est = Estimator(cell, config.estimator)
    events: list[LoopEvent] = []
    t, k_read, t_sample = 0.0, 0, -math.inf
    aborted = False
    while True:
        F = world.tension.max(axis=1)
        over = np.nonzero((F >= F_abort) & (world.t <= sched.cycle_time + 1e-9))[0]
        t_next = min(t + config.refresh_period, sched.cycle_time)
        bounds = [s.t_start for s in sched.plan.segments if t + 1e-9 < s.t_start < t_next]
        t_next = min(bounds) if bounds else t_next
        if not config.adaptive:            # the monitor watches the whole fixed run
            t_next = sched.cycle_time
        if over.size and world.t[over[0]] <= t_next:
            aborted = True
            t_a = float(world.t[over[0]])
            stop = stop_from_state(*sched.plan.sample(t_a), sched.plan.limits)
            stopped = splice(sched.plan, t_a, stop)
            world = run_world(true_cell, ScenarioPlan(stopped), t_end=t_a + stop.duration + 1.0,
                              lay=lay, numerics=numerics)
            break
        if t >= sched.cycle_time - 1e-9 or not config.adaptive:
            if not config.adaptive:
                t = sched.cycle_time
            break
        t = t_next
        new = []
        while k_read < world.t.size and world.t[k_read] <= t + 1e-9:
            if world.t[k_read] >= t_sample + config.sample_period - 1e-9:
                new.append(noisy(_sample(world, k_read), config.noise, rng))
                t_sample = float(world.t[k_read])
            k_read += 1
        estimate = est.update(new)
        tool = world.tool[max(k_read - 1, 0)]
        rp = replan(cell, estimate, sched, t, limits,
                    executed_xz=(float(tool[0]), float(tool[1])))
        changed = rp.changed and rp.schedule is not sched       # a new plan: run it
        if changed:
            sched = rp.schedule
        elif rp.status is ReplanStatus.NO_ESTIMATE and sched.choice != fixed_choice:
            back = sched.rejoin(t, fixed_choice)
            changed = back is not None
            sched = back if back is not None else sched
        if changed:
            world = _world(true_cell, sched, lay, numerics)
        events.append(LoopEvent(t, estimate, rp))
    end = world.t <= (world.t[-1] if aborted else sched.cycle_time + 1e-9)
    F_hist = world.tension.max(axis=1)
    F_max = float(F_hist[end].max())
    delta = math.inf if aborted else residual_gap(world.nodes(int(np.nonzero(end)[0][-1])),
                                                  true_cell.sheet.thickness)
    return LoopResult(adaptive=config.adaptive, aborted=aborted,
                      torn=F_max >= true_cell.material.F_break, F_max=F_max, delta=delta,
                      cycle_time=math.inf if aborted else sched.cycle_time, F_abort=F_abort,
                      events=tuple(events), history=(world.t[end], F_hist[end]),
                      gaps=_gaps(world, end), choice=sched.choice)


Series = tuple[np.ndarray, np.ndarray]


def _gaps(world: WorldRun, keep: np.ndarray, spacing: float = 0.5) -> Series:
    """The world's gap Delta [m] every ``spacing`` [s] of the samples ``keep``."""
    ks = np.nonzero(keep)[0]
    ks = ks[np.r_[True, np.diff(np.floor(world.t[ks] / spacing)) > 0]]
    return world.t[ks], np.array([residual_gap(world.nodes(int(k)),
                                               world.params.sheet.thickness) for k in ks])
