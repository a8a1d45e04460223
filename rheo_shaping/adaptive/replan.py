"""The re-planner: the rest of the movement that ends soonest while the sheet, as the
pessimistic end of the estimate says, stays under the monitor's threshold and shapes.

Candidates are choices (:class:`~.schedule.Choice`) of the forced strokes' speed and the
dwells' length, from a grid.  Each is joined to the running plan at t_j
(:meth:`~.schedule.Schedule.rejoin`: no jump in set-point, velocity or acceleration,
within the tool's limits) and predicted by the core's sheet model with the material at
the pessimistic corner of the estimate for each limit, kappa sigmas off (s: the estimate's
1-sigma of each logarithm),

    tension:  k1 e^{+kappa s_k1},  c2 e^{+kappa s_c2},  m e^{+kappa s_m}
    gap:      k1 e^{-kappa s_k1},  c2 e^{+kappa s_c2},  m e^{-kappa s_m}

(a stiffer, more viscous, heavier sheet pulls harder; a softer, more viscous, lighter one
closes the gap less: the signs of the model's sensitivities on movements 1-4, checked in
test/adaptive), the sheet at t_j taken once per corner from the executed tool path and each
candidate's future stepped from it (the gap corner only for a candidate whose tension
passes).  A candidate is feasible when

    max_{t >= t_j} F(t) <= F_limit   and   Delta(T_c) <= Delta_max,

with F_limit the monitor's threshold less 3 sigma of tension noise (its threshold itself
is principle 4's F_break - r (t_detect + t_stop) - 3 sigma: rheo_shaping.safety.abort_budget)
and T_c the candidate's cycle time.  Both limits get worse with a faster stroke and a shorter
dwell, so an infeasible (speed, dwell) rules out every faster and shorter one: the grid is
searched in order of cycle time and pruned so.  When no candidate meets both limits, the
one that keeps the sheet whole (lowest predicted tension) is chosen and the status says so.
No ROS here.
"""
from __future__ import annotations

import enum
import math
import time
from dataclasses import dataclass, replace

import numpy as np

from ..params.cell import CellParams
from ..params.validators import check_finite, check_positive
from ..planning.scenarios import ScenarioPlan
from ..sheet.chain import ConvergenceError
from ..sheet.simulation import Simulation
from .estimator import Estimate
from .schedule import Choice, Schedule
from .settle import LinearSettle, theta_of


class ReplanStatus(enum.Enum):
    """What :func:`replan` did."""

    REPLANNED = "replanned"      # a new rest of the movement, predicted to meet both limits
    KEPT = "kept"                # the running plan meets both and nothing is enough faster
    INFEASIBLE = "infeasible"    # no candidate meets both: the one keeping the sheet whole
    NO_ESTIMATE = "no_estimate"  # the estimate is bad: nothing re-planned (fall back)
    DONE = "done"                # the forced strokes are over: nothing left to choose


@dataclass(frozen=True)
class ReplanLimits:
    """What a re-plan must keep: ``F_limit`` [N] (the monitor's threshold less its noise
    margin), ``delta_max`` [m] (the quality limit, paper Sec. 4.1: 5 mm) less ``gap_margin``
    [m] (the model's form error on the gap, kept off the limit), the stroke speeds
    [m/s] and dwell factors [-] it may choose (speeds within the abort budget's 5x of the
    paper's 1 mm/s and the tool's limits), ``kappa`` (sigmas to the pessimistic end),
    ``min_gain`` [s] (a plan is changed for at least this much less cycle time) and
    ``max_evaluations`` (predictions per re-plan)."""

    F_limit: float
    delta_max: float = 5e-3
    gap_margin: float = 0.0
    speeds: tuple[float, ...] = (0.5e-3, 0.75e-3, 1e-3, 1.5e-3, 2e-3, 3e-3, 4e-3, 5e-3)
    dwell_factors: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0, 1.5)
    kappa: float = 2.0
    min_gain: float = 1.0
    max_evaluations: int = 12

    def __post_init__(self) -> None:
        check_positive("ReplanLimits.F_limit [N]", self.F_limit)
        check_positive("ReplanLimits.delta_max [m]", self.delta_max)
        check_finite("ReplanLimits.gap_margin [m]", self.gap_margin, non_negative=True)
        if self.gap_margin >= self.delta_max:
            raise ValueError(f"ReplanLimits.gap_margin = {self.gap_margin!r} m: expected "
                             f"less than delta_max ({self.delta_max!r} m)")
        check_finite("ReplanLimits.kappa [-]", self.kappa, non_negative=True)
        check_finite("ReplanLimits.min_gain [s]", self.min_gain, non_negative=True)
        if not self.speeds or not self.dwell_factors:
            raise ValueError(f"ReplanLimits.speeds = {self.speeds!r}, dwell_factors = "
                             f"{self.dwell_factors!r}: expected at least one of each")
        for v in self.speeds:
            check_positive("ReplanLimits.speeds [m/s]", v)
        for w in self.dwell_factors:
            check_finite("ReplanLimits.dwell_factors [-]", w, non_negative=True)
        if self.max_evaluations < 1:
            raise ValueError(f"ReplanLimits.max_evaluations = {self.max_evaluations!r}: "
                             "expected an integer >= 1")

    @property
    def gap_limit(self) -> float:
        """The largest predicted gap a plan may end with [m]: delta_max - gap_margin."""
        return self.delta_max - self.gap_margin


@dataclass(frozen=True)
class Prediction:
    """A candidate's predicted largest tension after the join [N], gap at its cycle end
    [m] and cycle time [s]."""

    choice: Choice
    F_max: float
    delta: float
    cycle_time: float
    complete: bool = True       # False: its run stopped past the tension limit (F_max a bound)

    def feasible(self, limits: ReplanLimits) -> bool:
        """Both limits met."""
        return self.F_max <= limits.F_limit and self.delta <= limits.gap_limit

    def whole(self, limits: ReplanLimits) -> bool:
        """The tension limit met (the sheet stays whole; the gap may not close)."""
        return self.F_max <= limits.F_limit


@dataclass(frozen=True)
class Replan:
    """The result of :func:`replan` (scipy ``OdeResult`` style): ``status`` and
    ``message``; ``schedule`` the plan to follow from t = 0 (the running one when nothing
    changed); ``t_join`` [s]; ``prediction`` of the chosen rest (None when none was made);
    ``evaluations`` candidates predicted; ``cost_s`` CPU time [s] of the re-plan."""

    status: ReplanStatus
    message: str
    schedule: Schedule
    t_join: float
    prediction: Prediction | None = None
    evaluations: int = 0
    cost_s: float = 0.0

    @property
    def changed(self) -> bool:
        """The schedule to follow is a new one (REPLANNED or INFEASIBLE)."""
        return self.status in (ReplanStatus.REPLANNED, ReplanStatus.INFEASIBLE)


#: Steps per kernel call of a tension corner's run that may stop past the limit.
CHUNK = 32

#: The corners (z_k1, z_c2, z_m) per kappa: where each limit is worst (module docstring).
TENSION_CORNER = (1.0, 1.0, 1.0)
GAP_CORNER = (-1.0, 1.0, -1.0)


#: Each corner's settled sheets (settle.py), per params file's cell: a corner moves from
#: re-plan to re-plan as the estimate narrows and comes to rest once it has.
_SETTLES: dict[tuple[CellParams, tuple[float, float, float]], LinearSettle] = {}


def _corner_start(base: CellParams, corner: CellParams, z: tuple[float, float, float]):
    """The settled sheet of the ``corner`` cell (the params file's ``base`` with the corner's
    material), to first order about where that corner came to rest (:mod:`.settle`)."""
    key = (base, z)
    if key not in _SETTLES:
        if len(_SETTLES) >= 16:
            _SETTLES.clear()
        _SETTLES[key] = LinearSettle.about(base)
    return _SETTLES[key].follow(theta_of(base, corner))


class _Corner:
    """The sheet at one corner, at t_j on the executed path, and its futures."""

    def __init__(self, cell: CellParams, schedule: Schedule, t_join: float, start=None):
        path = ScenarioPlan(schedule.plan)
        self.sim = Simulation(cell, tool_start=path.position(0.0), start=start)
        self._advance(path, t_join)
        self.state = self.sim.state.copy()

    def _advance(self, path: ScenarioPlan, t_end: float,
                 stop_above: float = math.inf) -> tuple[float, bool]:
        """Step along ``path`` to ``t_end`` [s]: (the largest tension [N] on the way, whether
        it got there).  Past ``stop_above`` [N] it stops (the candidate is infeasible
        whatever comes after); the steps are those of one kernel call per knot, run
        :data:`CHUNK` at a time when it may stop (the same steps, the same states)."""
        peak = -math.inf
        knots = [k for k in path.knots() if self.sim.state.t < k < t_end] + [t_end]
        for k in knots:
            if k <= self.sim.state.t:
                continue
            dts, poses = self.sim.schedule(k, path.position(k), path.position)
            size = CHUNK if stop_above < math.inf else max(len(dts), 1)
            for i in range(0, len(dts), size):
                rec = self.sim.advance_path(dts[i:i + size], poses[i:i + size])
                if len(rec):
                    peak = max(peak, float(np.max(rec.tension)))
                if peak > stop_above:
                    return peak, False
        return peak, True

    def future(self, schedule: Schedule, stop_above: float = math.inf
               ) -> tuple[float, float, bool]:
        """(largest tension [N] from t_j, gap [m] at the cycle's end, complete) of
        ``schedule``; past ``stop_above`` [N] the run stops: the gap is inf and complete
        False."""
        self.sim.state = self.state.copy()
        start = float(np.max(self.state.tension))
        try:
            peak, complete = self._advance(ScenarioPlan(schedule.plan), schedule.cycle_time,
                                           stop_above)
            delta = self.sim.delta() if complete else math.inf
        except (ConvergenceError, FloatingPointError, ValueError):
            return math.inf, math.inf, True
        return max(peak, start), delta, complete


class _Predictor:
    """Both corners of an estimate; a candidate's gap is predicted only when its tension
    passes (else it is inf: infeasible either way)."""

    def __init__(self, cell: CellParams, estimate: Estimate, schedule: Schedule,
                 t_join: float, limits: ReplanLimits):
        horizon = max(schedule.cycle_time, t_join) + 600.0

        def corner(z: tuple[float, float, float]) -> _Corner:
            c = estimate.cell(cell, tuple(limits.kappa * v for v in z))
            start = _corner_start(cell, c, z)
            c = replace(c, movement=replace(c.movement, process_time=horizon))
            return _Corner(c, schedule, t_join, start)

        self.limits = limits
        self.tension = corner(TENSION_CORNER)
        self.gap = corner(GAP_CORNER)

    def future(self, schedule: Schedule, whole_run: bool = False) -> Prediction:
        """The prediction of ``schedule``: its tension corner run stops once past the limit
        (then F_max is a lower bound and ``complete`` False) unless ``whole_run``."""
        F, _, complete = self.tension.future(
            schedule, math.inf if whole_run else self.limits.F_limit)
        delta = self.gap.future(schedule)[1] if F <= self.limits.F_limit else math.inf
        return Prediction(schedule.choice, F, delta, schedule.cycle_time, complete)


def replan(cell: CellParams, estimate: Estimate, schedule: Schedule, t_join: float,
           limits: ReplanLimits, executed_xz: tuple[float, float] | None = None,
           pose_tolerance: float = 1e-3) -> Replan:
    """The rest of the movement from ``t_join`` [s] (process time) for the material of
    ``estimate`` (its pessimistic end), on the params file's ``cell``.  ``executed_xz``
    [m], the executed tool pose at ``t_join``, must lie within ``pose_tolerance`` [m] of the
    running plan's set-point (the new plan starts from that state)."""
    wall = time.process_time()
    t_join = check_finite("t_join [s]", t_join, non_negative=True)

    def done(status: ReplanStatus, message: str, sched: Schedule = schedule,
             pred: Prediction | None = None, n: int = 0) -> Replan:
        return Replan(status, message, sched, t_join, pred, n, time.process_time() - wall)

    if not estimate.status.usable:
        return done(ReplanStatus.NO_ESTIMATE, f"estimate {estimate.status.value}: "
                    f"{estimate.message}; the running plan is kept")
    if executed_xz is not None:
        off = float(np.hypot(*(np.asarray(executed_xz, float)
                               - schedule.plan.sample(t_join)[0])))
        if not off <= pose_tolerance:
            return done(ReplanStatus.NO_ESTIMATE, f"the executed tool pose is {off:.3g} m from "
                        f"the set-point at t = {t_join:.2f} s (expected <= {pose_tolerance:g} "
                        "m): no re-plan on a tool that does not follow")
    if schedule.rejoin(t_join, schedule.choice) is None:
        return done(ReplanStatus.DONE, f"t = {t_join:.2f} s: the forced strokes are over")
    predictor = _Predictor(cell, estimate, schedule, t_join, limits)
    current = predictor.future(schedule)
    n = 1
    preds: list[tuple[Prediction, Schedule]] = [(current, schedule)]
    best: tuple[Prediction, Schedule] | None = None
    bound = current.cycle_time - limits.min_gain if current.feasible(limits) else math.inf
    speeds = sorted(limits.speeds, reverse=True)            # fastest first
    dwells = sorted(limits.dwell_factors)                   # shortest first
    # The feasible set is closed under a slower stroke and a longer dwell: the shortest
    # feasible dwell can only shorten as the stroke slows.  The staircase walk (saddleback
    # search) from the fastest stroke with the longest dwell finds that frontier with at
    # most len(speeds) + len(dwells) predictions; a candidate whose cycle time cannot beat
    # the best so far is passed over as if feasible (every slower one is longer still).
    i, j = 0, len(dwells) - 1
    while i < len(speeds) and j >= 0 and n < limits.max_evaluations:
        s = schedule.rejoin(t_join, Choice(speeds[i], dwells[j]))
        assert s is not None                              # the forced strokes are not over
        if s.cycle_time >= (best[0].cycle_time if best else bound):
            j -= 1
            continue
        p = predictor.future(s)
        n += 1
        preds.append((p, s))
        if p.feasible(limits):
            best = (p, s)
            j -= 1                                        # a shorter dwell at this speed?
        else:
            i += 1                                        # this dwell needs a slower stroke
    if best is not None:
        return done(ReplanStatus.REPLANNED, _words("chose", best[0], limits, estimate),
                    best[1], best[0], n)
    if current.feasible(limits):
        return done(ReplanStatus.KEPT, _words("kept", current, limits, estimate), schedule,
                    current, n)
    safest = schedule.rejoin(t_join, Choice(min(limits.speeds), max(limits.dwell_factors)))
    assert safest is not None                         # the forced strokes are not over
    if all(p.choice != safest.choice for p, _ in preds):
        preds.append((predictor.future(safest), safest))
        n += 1
    whole = [ps for ps in preds if ps[0].whole(limits)]
    if not whole:                 # the lowest tension is chosen: each one's whole run
        preds = [(p if p.complete else predictor.future(sc, whole_run=True), sc)
                 for p, sc in preds]
    pred, chosen = (min(whole, key=lambda ps: (ps[0].delta, ps[0].cycle_time)) if whole
                    else min(preds, key=lambda ps: ps[0].F_max))
    return done(ReplanStatus.INFEASIBLE, "no rest of the movement meets both limits; "
                + _words("chose the one keeping the sheet whole", pred, limits, estimate),
                chosen, pred, n)


def _words(verb: str, p: Prediction, limits: ReplanLimits, est: Estimate) -> str:
    return (f"{verb} {p.choice.speed * 1e3:g} mm/s, dwell x{p.choice.dwell_factor:g}: "
            f"pessimistic F_max {p.F_max:.3f} N (limit {limits.F_limit:.3f}), Delta "
            f"{p.delta * 1e3:.2f} mm (limit {limits.gap_limit * 1e3:g}), cycle "
            f"{p.cycle_time:.1f} s; k1 {est.k1:.1f} N/m, c2 {est.c2:.0f} N s/m, m "
            f"{est.mass_per_length:.4f} kg/m (+-{100 * est.sigma_rel[0]:.1f}/"
            f"{100 * est.sigma_rel[1]:.1f}/{100 * est.sigma_rel[2]:.1f} %)")
