"""The paper's study (Sec. 4.2 and 5) on a cell, as data: no printing, no files.

* Movements 1-4 (Table 2): F_max, SF and Delta of each, with its phases
  (approach, forced deformation, dwell, release, settle) and force peaks.
* The movement-4 sweep of Fig. 18: F_max and both force peaks against the
  distance d of the tool from the cake in the vertical step, and the d where
  F_max is smallest.
* Fig. 19's variant: movement 1 at half speed (0.5e-3 m/s) and no stop, so
  that its forced deformation lasts as long as movement 1's forced
  deformation plus stop.
* Test case 1 (Sec. 4.2): the sheet sagging under gravity only, its profile
  at t = settle time (1 s) against the undeformed drape at t = 0.

Every run is independent, so a caller can hand any
:class:`concurrent.futures.Executor` (:mod:`rheo_shaping.parallel`: a local
process pool, a Dask cluster) to run them in parallel; the worker functions
are module-level so they pickle.  :func:`reproduce` gathers it all in a
:class:`Study`, and :meth:`Study.to_json` is the ``--json`` object of
``rheo-shaping reproduce``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from concurrent.futures import Executor
from typing import Callable, Sequence, TypedDict

import numpy as np

from ..jsonable import json_safe
from ..parallel import run_tasks
from ..params.cell import CellParams
from ..planning.scenarios import FORCED, ScenarioPlan
from ..planning.movement import movement_plan
from ..sheet.metrics import touching_tool
from ..sheet.simulation import RunResult, Simulation, run_scenario
from .sweep import Sweep, sweep_of


class PaperMovement(TypedDict):
    """The paper's figures of one movement: F_max [N], SF [-], delta [m]."""

    F_max: float
    SF: float
    delta: float


class PaperFigures(TypedDict):
    """The paper's figures the study is checked against (:data:`PAPER`)."""

    movements: dict[str, PaperMovement]
    d_opt: float                 # m
    half_speed: dict[str, float]
    delta_limit: float           # m


#: The paper's numbers (Table 2, Fig. 18, Fig. 19); SF = F_break / F_max.
PAPER: PaperFigures = {
    "movements": {
        "1": {"F_max": 0.845, "SF": 1.23, "delta": 2.67e-3},
        "2": {"F_max": 0.837, "SF": 1.24, "delta": 3.01e-3},
        "3": {"F_max": 1.005, "SF": 1.03, "delta": 3.08e-3},
        "4": {"F_max": 0.658, "SF": 1.58, "delta": 4.00e-3},
    },
    "d_opt": 14.5e-3,
    "half_speed": {"delta": 6.6e-3},
    "delta_limit": 5e-3,
}

MOVEMENT_NAMES = {1: "vertical", 2: "horizontal", 3: "inclined 45 deg", 4: "two-step"}

#: Fig. 18's range of d [m] (the issue's 5e-3 to 30e-3 m), 1 mm apart.
DEFAULT_D_VALUES = tuple(float(v) for v in np.round(np.arange(5e-3, 30e-3 + 1e-9, 1e-3), 6))

#: Fig. 19: movement 1 at half the tool speed and without the stop.
HALF_SPEED = 0.5e-3


# ----------------------------------------------------------------- one movement
@dataclass
class MovementRun:
    """One run of a movement: the simulator's result and what the study reads off it."""

    label: str
    number: int
    speed: float                                # m/s
    dwell: float                                # s
    d: float | None                             # m, movement 4 only
    result: RunResult
    plan: ScenarioPlan
    # (t0, t1, name): approach, forced, dwell, release, settle
    phases: list[tuple[float, float, str]]
    # (time [s], largest link tension [N]) of each forcing move
    peaks: list[tuple[float, float]]
    # s, when the tool first touches the sheet (nan: never)
    first_contact: float
    last_contact: float                         # s, when it last touches it
    # s, tool in contact while moving to its end of travel
    forced_time: float
    contacts_at_peak: int                       # spheres touching the tool when F_max occurs
    # fewest spheres touching the tool during the dwell(s)
    min_contacts_forced: int

    @property
    def F_max(self) -> float:
        return self.result.F_max

    @property
    def SF(self) -> float:
        return self.result.SF

    @property
    def delta(self) -> float:
        return self.result.delta

    def summary(self) -> dict:
        out = {**self.result.run_summary.as_dict(), "speed": self.speed, "dwell": self.dwell,
               "peaks": [{"time": t, "F": f} for t, f in self.peaks],
               "first_contact": _finite_or_none(self.first_contact),
               "last_contact": _finite_or_none(self.last_contact),
               "forced_time": self.forced_time, "contacts_at_peak": self.contacts_at_peak,
               "min_contacts_dwell": self.min_contacts_forced,
               "phases": [{"start": a, "end": b, "name": n} for a, b, n in self.phases]}
        if self.d is not None:
            out["d"] = self.d
        return out


def _finite_or_none(x: float):
    return json_safe(float(x))


def _touching(result: RunResult) -> np.ndarray:
    """(K, N) bool: which spheres touch the tool at each step."""
    return touching_tool(result.tool_contact)


def movement_phases(plan: ScenarioPlan,
                    result: RunResult) -> tuple[list[tuple[float, float, str]], dict]:
    """The paper's phases of a run (Sec. 5), from the plan's segments and the contacts.

    approach: until the tool first touches the sheet; forced: the tool moving
    toward its end of travel in contact; dwell: the stops at the end of
    travel; release: retracting while still in contact; settle: after the
    tool has left the sheet.  Returns the phases and the contact times.
    """
    t = result.t
    touching = _touching(result).any(axis=1)
    hit = np.flatnonzero(touching)
    t_first = float(t[hit[0]]) if hit.size else math.inf
    t_last = float(t[hit[-1]]) if hit.size else -math.inf
    t_end = float(t[-1])
    phases: list[tuple[float, float, str]] = []
    forced_time = 0.0
    retract_start = None
    for seg in plan.plan.segments:
        a, b = min(seg.t_start, t_end), min(seg.t_end, t_end)
        if b <= a:
            continue
        if seg.kind == "dwell":
            phases.append((a, b, "dwell"))
        elif seg.label.startswith(FORCED):
            c = min(max(a, t_first), b)
            if c > a:
                phases.append((a, c, "approach"))
            if b > c:
                phases.append((c, b, FORCED))
                forced_time += b - c
        else:                                       # retract
            if retract_start is None:
                retract_start = a
    if retract_start is not None and retract_start < t_end:
        c = min(max(retract_start, t_last), t_end)
        if c > retract_start:
            phases.append((retract_start, c, "release"))
        if t_end > c:
            phases.append((c, t_end, "settle"))
    elif phases and phases[-1][1] < t_end:
        phases.append((phases[-1][1], t_end, "settle"))
    return phases, {"first": t_first, "last": t_last, "forced_time": forced_time}


def force_peaks(plan: ScenarioPlan, result: RunResult) -> list[tuple[float, float]]:
    """Largest link tension in each window that starts with a forcing move (Fig. 17's peaks)."""
    starts = [s.t_start for s in plan.plan.segments if s.kind ==
              "move" and s.label.startswith(FORCED)]
    if not starts:
        return []
    starts[0] = 0.0                                # the first window covers the approach too
    bounds = starts + [math.inf]
    peak_per_step = result.tension.max(axis=1)
    out = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        k = np.flatnonzero((result.t >= a) & (result.t < b))
        if k.size == 0:
            continue
        j = k[int(np.argmax(peak_per_step[k]))]
        out.append((float(result.t[j]), float(peak_per_step[j])))
    return out


def movement_run(params: CellParams, number: int, speed: float | None = None,
                 dwell: float | None = None, d: float | None = None,
                 label: str | None = None) -> MovementRun:
    """Run the paper's movement ``number`` on the cell (defaults: the cell's speed, dwell and
    d)."""
    speed = params.movement.speed if speed is None else float(speed)
    dwell = params.movement.dwell if dwell is None else float(dwell)
    if number == 4:
        d = params.movement.d if d is None else float(d)
    else:
        d = None
    plan = movement_plan(params, number, speed=speed, dwell=dwell, d=d)
    result = run_scenario(params, plan)
    phases, contact = movement_phases(plan, result)
    touching = _touching(result)
    k_peak = int(np.argmin(np.abs(result.t - result.peak.time)))
    in_dwell = np.zeros(result.t.size, dtype=bool)
    for a, b, name in phases:
        if name == "dwell":
            in_dwell |= (result.t > a) & (result.t <= b)
    counts = touching.sum(axis=1)
    return MovementRun(
        label=label or str(number), number=number, speed=speed, dwell=dwell, d=d,
        result=result, plan=plan, phases=phases, peaks=force_peaks(plan, result),
        first_contact=contact["first"], last_contact=contact["last"],
        forced_time=contact["forced_time"], contacts_at_peak=int(counts[k_peak]),
        min_contacts_forced=int(counts[in_dwell].min()) if in_dwell.any() else 0)


# ------------------------------------------------------------------------ sweep
def sweep_point(params: CellParams, d: float) -> dict:
    """One point of the sweep: movement 4 at ``d`` [m] (module-level: pickles to a worker)."""
    run = movement_run(params, 4, d=d)
    peaks = [f for _, f in run.peaks] + [0.0, 0.0]
    return {"d": float(d), "F_max": run.F_max, "peak1": peaks[0], "peak2": peaks[1],
            "delta": run.delta}


def d_sweep(params: CellParams, d_values: Sequence[float] = DEFAULT_D_VALUES,
            executor: Executor | None = None,
            progress: Callable[[int], None] | None = None) -> Sweep:
    """Fig. 18 on the cell: movement 4 at every d of ``d_values`` [m] (on ``executor``)."""
    rows = run_tasks(executor, _study_task, params, [("d", float(d)) for d in d_values],
                     progress)
    return sweep_of(rows)


# ------------------------------------------------------------------ test case 1
@dataclass
class SagTest:
    """Test case 1: the undeformed drape (t = 0) and the sheet after sagging under gravity."""

    time: float              # s, how long it sagged (solver.settle_time)
    undeformed: np.ndarray   # (N+2, 2) m, bonds and masses
    sagged: np.ndarray       # (N+2, 2) m
    max_displacement: float  # m, largest displacement of a mass
    length: float            # m, rest length of the sheet
    top_tension: float       # N, tension of the top link after sagging

    @property
    def relative_displacement(self) -> float:
        """Largest displacement relative to the sheet's length (the paper's error is relative
        too)."""
        return self.max_displacement / self.length


def sag_test(params: CellParams) -> SagTest:
    sim = Simulation(params)
    undeformed = np.vstack((sim.constants.anchor_top, sim.x0, sim.constants.anchor_bottom))
    sagged = sim.nodes()
    disp = float(np.max(np.hypot(*(sagged - undeformed).T)))
    return SagTest(time=params.solver.settle_time, undeformed=undeformed, sagged=sagged,
                   max_displacement=disp, length=float(sim.constants.rest_length.sum()),
                   top_tension=float(sim.state.tension[0]))


# ------------------------------------------------------------------------ study
def _study_task(params: CellParams, job: tuple):
    """One run of the study: ("d", d) for the sweep or ("movement", label, number, speed,
    dwell) (module-level: pickles to a worker)."""
    if job[0] == "d":
        return sweep_point(params, job[1])
    _, label, number, speed, dwell = job
    return movement_run(params, number, speed=speed, dwell=dwell, label=label)


@dataclass
class Study:
    """Everything ``rheo-shaping reproduce`` shows."""

    params: CellParams = field(repr=False)
    movements: dict[str, MovementRun]
    half_speed: MovementRun
    sweep: Sweep
    sag: SagTest

    def to_json(self) -> dict:
        """The ``--json`` object: the issue's keys (SI units) and a few more."""
        mv = {k: {"F_max": r.F_max, "SF": r.SF, "delta": r.delta}
              for k, r in self.movements.items()}
        return {
            "movements": mv,
            "d_sweep": {"d": self.sweep.d.tolist(), "F_max": self.sweep.F_max.tolist(),
                        "peak1": self.sweep.peak1.tolist(), "peak2": self.sweep.peak2.tolist(),
                        "delta": self.sweep.delta.tolist()},
            "d_opt": self.sweep.d_opt,
            "half_speed": {"F_max": self.half_speed.F_max, "delta": self.half_speed.delta,
                           "SF": self.half_speed.SF, "speed": self.half_speed.speed,
                           "forced_time": self.half_speed.forced_time},
            "details": {k: r.summary() for k, r in self.movements.items()},
            "test_case_1": {"time": self.sag.time, "max_displacement": self.sag.max_displacement,
                            "relative_displacement": self.sag.relative_displacement,
                            "top_tension": self.sag.top_tension},
            "paper": PAPER,
        }

    def checks(self) -> dict[str, bool]:
        """The issue's acceptance orderings (magnitudes are in :func:`magnitude_checks`)."""
        F = {k: r.F_max for k, r in self.movements.items()}
        D = {k: r.delta for k, r in self.movements.items()}
        lim = PAPER["delta_limit"]
        return {
            "F_max: movement 3 largest": max(F, key=F.__getitem__) == "3",
            "F_max: movement 4 smallest": min(F, key=F.__getitem__) == "4",
            "Delta of movements 1-4 below 5 mm": all(v < lim for v in D.values()),
            "half speed: F_max below movement 1": self.half_speed.F_max < F["1"],
            "half speed: Delta above 5 mm": self.half_speed.delta > lim,
            "d sweep: interior minimum": self.sweep.interior,
            "d sweep: peaks (nearly) equal at the minimum": self.sweep.peak_gap_at_min < 0.1,
        }

    def magnitude_checks(self) -> dict[str, bool]:
        """The issue's magnitudes: F_max within 10 %, Delta within 0.5 mm, d_opt within 3 mm."""
        out = {}
        for k, r in self.movements.items():
            ref = PAPER["movements"][k]
            out[f"movement {k}: F_max within 10 %"] = abs(r.F_max / ref["F_max"] - 1.0) <= 0.10
            out[f"movement {k}: Delta within 0.5 mm"] = abs(r.delta - ref["delta"]) <= 0.5e-3
        out["d_opt within 3 mm"] = abs(self.sweep.d_opt - PAPER["d_opt"]) <= 3e-3
        return out


def reproduce(params: CellParams | None = None, d_values: Sequence[float] = DEFAULT_D_VALUES,
              executor: Executor | None = None,
              progress: Callable[[int], None] | None = None) -> Study:
    """The whole study on ``params`` (default: the default cell).

    The independent simulations (movements 1-4, the half-speed variant, the d
    sweep) run on ``executor`` (default: one after the other here);
    ``progress(k)`` is called as k more of the ``len(d_values) + 5`` runs finish.
    """
    params = CellParams() if params is None else params
    # ("movement", label, number, speed [m/s], dwell [s]) or ("d", d [m]): _study_task's jobs
    jobs: list[tuple[str, str, int, float | None, float | None] | tuple[str, float]]
    jobs = [("movement", str(n), n, None, None) for n in (1, 2, 3, 4)]
    jobs.append(("movement", "half_speed", 1, HALF_SPEED, 0.0))
    jobs += [("d", float(d)) for d in d_values]
    runs = run_tasks(executor, _study_task, params, jobs, progress)
    movements = {r.label: r for r in runs[:4]}
    sweep = sweep_of(runs[5:])
    return Study(params=params, movements=movements, half_speed=runs[4], sweep=sweep,
                 sag=sag_test(params))
