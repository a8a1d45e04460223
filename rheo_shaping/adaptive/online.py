"""The closed loop as the planner node runs it: samples of the running cell in, a new rest
of the movement out, joined ahead of what is already streamed.

:class:`OnlineShaper` holds the running :class:`~.schedule.Schedule` (its plan from t = 0
is the one the planner streams), keeps one sample per ``sample_period`` of process time,
says when a refresh is due (every ``refresh_period`` and at each boundary of the movement's
moves), and :meth:`~OnlineShaper.refresh` turns the samples into an estimate and a re-plan
joined ``join_lead`` seconds after the newest sample (the set-points before that are sent
while it computes).  The caller takes the new plan with :meth:`~OnlineShaper.accept` once
its stream has switched (:meth:`rheo_shaping.planning.stopping.TrajectoryStreamer.
replace_rest`), or drops it when the stream has already passed the join.  A bad estimate
falls back to the params file's choice.  Times are process time [s] from the run's start.
No ROS here.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import numpy as np

from ..params.cell import CellParams
from ..params.validators import check_finite, check_positive
from ..planning.plans import Plan
from .estimator import Estimate, Estimator, EstimatorParams
from .loop import replan_limits
from .observe import Sample
from .replan import Replan, ReplanLimits, ReplanStatus, replan
from .schedule import Schedule, fixed_schedule


class Reason(enum.Enum):
    """Why a refresh ran."""

    PERIOD = "period"          # refresh_period of process time since the last one
    BOUNDARY = "boundary"      # the tool entered another move or dwell of the movement


@dataclass(frozen=True)
class OnlineConfig:
    """The node's closed loop: ``sample_period`` [s] between samples kept,
    ``refresh_period`` [s] between refreshes, ``join_lead`` [s] from the newest sample to
    the join (longer than a refresh's compute time at the cell's speed), the largest
    distance [m] of the executed pose from the set-point for a re-plan
    (``pose_tolerance``), the estimator's settings and the monitor's budget (detect time
    [s], tension noise [N]) the re-planner keeps under."""

    sample_period: float = 0.5
    refresh_period: float = 2.0
    join_lead: float = 1.0
    pose_tolerance: float = 1e-3
    estimator: EstimatorParams = field(default_factory=EstimatorParams)
    detect_time: float = 0.1
    noise_sigma: float = 0.005

    def __post_init__(self) -> None:
        for name in ("sample_period", "refresh_period", "join_lead", "pose_tolerance",
                     "detect_time", "noise_sigma"):
            check_positive(f"OnlineConfig.{name}", getattr(self, name))


@dataclass(frozen=True)
class OnlineStep:
    """One refresh: when (``t``, process time [s]), why, the join time [s], the estimate,
    the re-plan (None when none was tried), the plan to stream from ``t_join`` on (None:
    keep the running one) and a sentence for the log."""

    t: float
    reason: Reason
    t_join: float
    estimate: Estimate
    replan: Replan | None
    plan: Plan | None
    message: str
    schedule: Schedule = field(repr=False)

    def as_dict(self) -> dict:
        """Plain numbers for ``/shaping/estimate`` (SI units)."""
        return {"t": self.t, "reason": self.reason.value, "t_join": self.t_join,
                "estimate": self.estimate.as_dict(),
                "replan": None if self.replan is None else self.replan.status.value,
                "replanned": self.plan is not None, "message": self.message,
                "choice": {"speed": self.schedule.choice.speed,
                           "dwell_factor": self.schedule.choice.dwell_factor},
                "cycle_time": self.schedule.cycle_time}


class OnlineShaper:
    """The closed loop's state for one run of the params file's ``cell``."""

    def __init__(self, cell: CellParams, config: OnlineConfig = OnlineConfig(),
                 limits: ReplanLimits | None = None):
        self.cell = cell
        self.config = config
        self.schedule = fixed_schedule(cell)
        self._fixed = self.schedule.choice
        self.limits = (replan_limits(cell, config.detect_time, config.noise_sigma)
                       if limits is None else limits)
        self.estimator = Estimator(cell, config.estimator)
        self._pending: list[Sample] = []
        self._t_sample = -math.inf
        self._t_refresh = 0.0
        self._where = self.schedule.move_at(0.0)[:2]
        self.steps: list[OnlineStep] = []

    @property
    def plan(self) -> Plan:
        """The plan from t = 0 the tool follows (the params file's until a re-plan)."""
        return self.schedule.plan

    def wants(self, t: float) -> bool:
        """Would a sample at process time ``t`` [s] be kept (``sample_period`` since the
        last one kept)?"""
        return t >= self._t_sample + self.config.sample_period - 1e-9

    def add(self, sample: Sample) -> bool:
        """Keep ``sample`` if :meth:`wants` its time."""
        t = check_finite("Sample.t [s]", sample.t)
        if not self.wants(t):
            return False
        self._pending.append(sample)
        self._t_sample = t
        return True

    def due(self, t: float) -> Reason | None:
        """Why a refresh is due at process time ``t`` [s] (None: not yet)."""
        if self.schedule.move_at(t)[:2] != self._where:
            return Reason.BOUNDARY
        if t >= self._t_refresh + self.config.refresh_period - 1e-9:
            return Reason.PERIOD
        return None

    def refresh(self, t: float, reason: Reason,
                executed_xz: tuple[float, float] | None = None,
                streamed: float | None = None, lead: float | None = None) -> OnlineStep:
        """The estimate from the samples kept and, when it is usable, the rest of the
        movement joined ``join_lead`` [s] after the later of ``t`` and ``streamed`` (the
        newest set-point time sent [s]; ``lead`` [s] instead of ``join_lead`` when longer: the
        process time a refresh takes at the cell's speed); ``executed_xz`` [m] is the
        executed tool pose at
        ``t`` (a tool further than ``pose_tolerance`` from its set-point is not
        re-planned)."""
        t = check_finite("t [s]", t, non_negative=True)
        self.begin(t)
        estimate = self.estimator.update(self._pending)
        self._pending = []
        lead = max(self.config.join_lead, 0.0 if lead is None else float(lead))
        t_join = max(t, t if streamed is None else float(streamed)) + lead
        sched = self.schedule
        if executed_xz is not None:
            off = float(np.hypot(*(np.asarray(executed_xz, float) - sched.plan.sample(t)[0])))
            if not off <= self.config.pose_tolerance:
                return self._step(t, reason, t_join, estimate, None, sched,
                                  f"no re-plan: the executed tool pose is {off * 1e3:.2f} mm "
                                  f"from its set-point (tolerance "
                                  f"{self.config.pose_tolerance * 1e3:g} mm)")
        rp = replan(self.cell, estimate, sched, t_join, self.limits)
        if rp.changed:
            return self._step(t, reason, t_join, estimate, rp, rp.schedule, rp.message)
        if rp.status is ReplanStatus.NO_ESTIMATE and sched.choice != self._fixed:
            back = sched.rejoin(t_join, self._fixed)
            if back is not None:
                return self._step(t, reason, t_join, estimate, rp, back,
                                  f"{rp.message}; back to the params file's plan")
        return self._step(t, reason, t_join, estimate, rp, sched, rp.message)

    def begin(self, t: float, drop_samples: bool = False) -> None:
        """A refresh begins at process time ``t`` [s]: the next is due from here (and the
        samples kept are dropped: a bookkeeping copy whose refresh runs elsewhere)."""
        self._t_refresh, self._where = t, self.schedule.move_at(t)[:2]
        if drop_samples:
            self._pending = []

    def accept(self, step: OnlineStep) -> None:
        """The stream follows ``step``'s plan from its join on."""
        if step.plan is not None:
            self.schedule = step.schedule

    def _step(self, t: float, reason: Reason, t_join: float, estimate: Estimate,
              rp: Replan | None, sched: Schedule, message: str) -> OnlineStep:
        step = OnlineStep(t=t, reason=reason, t_join=t_join, estimate=estimate, replan=rp,
                          plan=None if sched is self.schedule else sched.plan,
                          message=message, schedule=sched)
        self.steps.append(step)
        return step
