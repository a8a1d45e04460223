"""Run the sheet model of a cell: the stepping API and whole scenarios.

:class:`Simulation` builds the chain of :mod:`rheo_shaping.sheet.chain` from
:class:`~rheo_shaping.params.cell.CellParams`.  On :meth:`Simulation.reset` the
undeformed drape sags under gravity with inertia for ``solver.settle_time``
(the paper's test case 1; steps of ``solver.dt_settle``); the process clock
then starts at t = 0 with that settled sheet.  The process takes the same
backward-Euler steps, but long ones, which makes it quasi-static (tool speeds
of mm/s against sheet vibration periods of ms; the inertia term m/dt^2 is
~1e-5 of the link stiffness):
steps of at most ``solver.dt`` while the tool moves (``solver.dt_still``
while it stands still) and at most ``solver.max_tool_step`` of tool travel.
``advance_to(t, tool_xz)`` is the stepping API of the ROS simulator node (the
tool moving linearly from its last pose); :func:`run_scenario` runs a whole
tool path for the CLI, the paper study and the diagnosis.  Both take the same
steps.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from .drape import make_drape
from .geometry import Cake, Workplane
from .metrics import (PeakTension, RunSummary, contact_tension, peak_tension, residual_gap,
                      safety_factor)
from ..params.cell import CellParams
from .chain import ChainConstants, Obstacle, SheetModel, SheetState, StepRecord
from .effects import sheet_effects
from .paths import PolylinePath, ToolPath
from .tools import tool_shape

#: Order of the obstacles in :attr:`SheetState.contact`.
CAKE, WORKPLANE, TOOL = 0, 1, 2


@dataclass(frozen=True)
class LaidSheet:
    """The sheet as it was laid, released from rest at ``t0`` [s]: the model's initial state
    taken from the records (:mod:`rheo_shaping.diagnosis.initial_state`) instead of the
    scenario's drape settled before t = 0.

    ``nodes`` (M, 2) [m]: the laid centreline from the cake-top bond to the workplane bond
    (the chain's masses at equal arc length along it); ``rest_length`` [m]: the links' total
    rest length (the laid length when the sheet was laid without strain); after ``t0`` the
    first ``release_time`` [s] take inertial steps of at most ``solver.dt_settle`` (the fall),
    then the process's steps."""

    nodes: np.ndarray
    rest_length: float
    t0: float = 0.0
    release_time: float = 1.0


def _polyline_at(nodes: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Points of polyline ``nodes`` (M, 2) at arc lengths ``s`` [m]."""
    cum = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(nodes, axis=0).T))))
    return np.c_[np.interp(s, cum, nodes[:, 0]), np.interp(s, cum, nodes[:, 1])]


def build_chain(params: CellParams,
                laid: LaidSheet | None = None) -> tuple[ChainConstants, np.ndarray]:
    """Chain constants and the initial (unstretched) mass positions: the scenario's drape,
    or ``laid``'s centreline (masses at equal arc length, links of equal rest length).

    Effects (params.effects): ``kelvin_c1`` adds to c1; ``mass_error`` scales the masses.
    """
    s, m, c, eff = params.sheet, params.material, params.cake, params.effects
    r = 0.5 * s.thickness
    n = s.n_masses
    if laid is None:
        drape = make_drape(c.height, c.fillet_radius, r, s.top_bond_x, s.bottom_bond_x,
                           s.excess_length)
        top, bottom = drape.top_bond, drape.bottom_bond
        x0 = drape.points(np.arange(1, n + 1) * drape.length / (n + 1))
        nodes = np.vstack((top, x0, bottom))
        link_rest = np.hypot(*np.diff(nodes, axis=0).T)   # unstretched at t = 0
    else:
        line = np.asarray(laid.nodes, float).reshape(-1, 2)
        total = float(np.hypot(*np.diff(line, axis=0).T).sum())
        if not (laid.rest_length > 0 and total > 0):
            raise ValueError(f"laid sheet: rest length {laid.rest_length!r} m and centreline "
                             f"length {total!r} m: expected both > 0")
        top, bottom = line[0].copy(), line[-1].copy()
        x0 = _polyline_at(line, np.arange(1, n + 1) * total / (n + 1))
        link_rest = np.full(n + 1, laid.rest_length / (n + 1))
    scale = m.specimen_length / link_rest              # k L0 / l (docs/paper.md, scaling)
    constants = ChainConstants(
        anchor_top=top, anchor_bottom=bottom,
        rest_length=link_rest, k1=m.k1 * scale, c1=(m.c1 + eff.kelvin_c1) * scale, c2=m.c2 * scale,
        mass=s.mass_per_length * (1.0 + eff.mass_error) * 0.5 * (link_rest[:-1] + link_rest[1:]),
        radius=r,
        gravity=params.solver.gravity)
    return constants, x0


class Simulation:
    """The sheet of one cell, stepped under a tool pose."""

    def __init__(self, params: CellParams, tool_start=None, laid: LaidSheet | None = None,
                 start: SheetState | None = None):
        """``start``: the sheet at t = 0 instead of the settled one (adaptive.settle's)."""
        if start is not None and laid is not None:
            raise ValueError("Simulation: give a laid sheet or a start state, not both")
        self.params, self.laid, self.start = params, laid, start
        self.constants, self.x0 = build_chain(params, laid)
        obstacles = [
            Obstacle("cake", Cake.of(params.cake)),
            Obstacle("workplane", Workplane()),
            Obstacle("tool", tool_shape(params.tool), moving=True),
        ]
        sp = params.solver
        self.model = SheetModel(self.constants, obstacles, sp.contact_stiffness,
                                sp.force_tol, sp.max_newton, sheet_effects(params))
        self.tool_start = np.asarray(params.tool.home if tool_start is None else tool_start, float)
        self.reset()

    def reset(self) -> None:
        """Back to t = 0: the settled sheet, tool at its start pose (a laid sheet: at rest in
        its laid shape at its release time)."""
        if self.laid is not None:
            self.state: SheetState = self.model.initial_state(self.x0, self.tool_start,
                                                              float(self.laid.t0))
        elif self.start is not None:
            self.state = replace(self.start.copy(), t=0.0, tool=self.tool_start.copy())
        else:
            self.state = settled_state(self.params, self.model, self.x0, self.tool_start)
        self.steps = 0

    def next_dt(self, t: float, t_end: float, tool_moving: bool) -> float:
        """Largest quasi-static step [s] from ``t`` toward ``t_end``."""
        sp = self.params.solver
        return min(sp.dt if tool_moving else sp.dt_still, t_end - t)

    def schedule(self, t_end: float, tool_end,
                 tool_at: Callable[[float], np.ndarray] | None = None, start=None):
        """The steps from the current state to ``t_end`` [s]: (dt (K,) [s], tool pose at the
        end of each step (K, 2) [m]).  The tool moves linearly from its last pose to
        ``tool_end`` (or follows ``tool_at(t)``); steps of at most ``solver.dt`` while it
        moves (``solver.dt_still`` while it stands) and ``solver.max_tool_step`` of travel.
        The schedule depends on the tool path only, not on the sheet: ``start`` (t [s],
        pose (2,) [m]) plans from there instead of from the current state."""
        t0 = self.state.t if start is None else float(start[0])
        if t_end < t0 - 1e-12:
            raise ValueError(f"t_end = {t_end!r} s is before the sheet's time {t0!r} s")
        p0 = (self.state.tool if start is None else np.asarray(start[1], dtype=float)).copy()
        p1 = np.asarray(tool_end, dtype=float)
        if tool_at is None:
            span = max(t_end - t0, 1e-300)
            tool_at = lambda t: p0 + (p1 - p0) * min(max((t - t0) / span, 0.0), 1.0)  # noqa: E731
        max_step = self.params.solver.max_tool_step
        dts: list[float] = []
        poses: list = []
        t, prev = t0, p0
        while t < t_end - 1e-12:
            dt = self.next_dt(t, t_end, tool_moving=True)
            pose = tool_at(t + dt)
            travel = math.hypot(pose[0] - prev[0], pose[1] - prev[1])
            if travel < 1e-12 * max_step:
                dt = self.next_dt(t, t_end, tool_moving=False)
                pose = tool_at(t + dt)
                travel = math.hypot(pose[0] - prev[0], pose[1] - prev[1])
            if travel > max_step:
                dt *= max_step / travel
                pose = tool_at(t + dt)
            if t_end - (t + dt) < 1e-9:
                dt, pose = t_end - t, tool_at(t_end)
            dts.append(dt)
            poses.append(pose)
            t, prev = t + dt, pose
        return np.array(dts, dtype=float), np.array(poses, dtype=float).reshape(-1, 2)

    def advance_record(self, t_end: float, tool_end,
                       tool_at: Callable[[float], np.ndarray] | None = None) -> StepRecord:
        """Advance to ``t_end`` [s] like :meth:`advance_to`, all steps in the compiled kernel;
        returns every step's state as arrays."""
        return self.advance_path(*self.schedule(t_end, tool_end, tool_at))

    def advance_path(self, dts: np.ndarray, tools: np.ndarray) -> StepRecord:
        """Steps of ``dts`` (K,) [s] with the tool at ``tools`` (K, 2) [m] at their ends (a
        :meth:`schedule`), in the compiled kernel; every step's state as arrays.  A failed
        step raises ConvergenceError after the sheet kept the steps before it."""
        rec = self.model.run_path(self.state, dts, tools)
        if len(rec):
            self.state = rec.state(len(rec) - 1)
            self.steps += len(rec)
        if rec.error is not None:
            raise rec.error
        return rec

    def advance_to(self, t_end: float, tool_end,
                   on_step: Callable[[SheetState], None] | None = None,
                   tool_at: Callable[[float], np.ndarray] | None = None) -> SheetState:
        """Advance to time ``t_end`` [s], the tool ending at ``tool_end`` (x, z) [m].

        Between the current time and ``t_end`` the tool moves linearly from its
        last pose (or follows ``tool_at(t)`` when given).  ``on_step`` is called
        with every sub-step's state (``self.state`` is that state during the call).
        """
        if on_step is None:
            self.advance_record(t_end, tool_end, tool_at)
            return self.state
        rec = self.model.run_path(self.state, *self.schedule(t_end, tool_end, tool_at))
        for k in range(len(rec)):
            self.state = rec.state(k)
            self.steps += 1
            on_step(self.state)
        if rec.error is not None:
            raise rec.error
        return self.state

    # ------------------------------------------------------------ outputs
    def nodes(self, state: SheetState | None = None) -> np.ndarray:
        """Bond, mass and bond positions (N+2, 2) [m]."""
        return self.model.nodes((state or self.state).x)

    def tool_force(self, state: SheetState | None = None) -> np.ndarray:
        """Force (x, z) [N] the sheet exerts on the tool."""
        return -np.sum((state or self.state).contact[TOOL], axis=0)

    def contact_tension(self, state: SheetState | None = None) -> float:
        st = state or self.state
        return contact_tension(st.tension, st.contact[TOOL])

    def delta(self, state: SheetState | None = None) -> float:
        return residual_gap(self.nodes(state), self.params.sheet.thickness)


def settle(model: SheetModel, x0: np.ndarray, duration: float, dt: float, tool=(np.nan, np.nan),
           on_step: Callable[[SheetState], None] | None = None) -> SheetState:
    """The undeformed drape ``x0`` sagging under gravity with inertia for ``duration`` [s].

    Backward-Euler steps of ``dt`` [s]; the returned state has its clock at
    ``duration``.  This is the paper's test case 1.
    """
    state = model.initial_state(x0, tool)
    n = int(np.ceil(duration / dt - 1e-9))
    if n <= 0:                                # settle_time 0: the undeformed drape as it is
        return replace(state, t=float(duration))
    if on_step is None:                       # all n steps in the compiled kernel
        return model.run_steps(state, duration / n, n, tool, dynamic=True)
    for _ in range(n):
        state = model.step(state, duration / n, tool, dynamic=True)
        on_step(state)
    return state


_SETTLED: dict = {}


def settled_state(params: CellParams, model: SheetModel, x0: np.ndarray, tool) -> SheetState:
    """The settled sheet at process time 0, cached per sheet, cake, material and solver."""
    sp = params.solver
    key = (params.material, params.sheet, params.cake, sp, params.effects)
    if key not in _SETTLED:
        if len(_SETTLED) > 64:
            _SETTLED.clear()
        st = settle(model, x0, sp.settle_time, sp.dt_settle)
        _SETTLED[key] = replace(st, t=0.0)
    st = _SETTLED[key].copy()
    return replace(st, tool=np.asarray(tool, dtype=float).copy())


@dataclass
class RunResult:
    """Time series of a run (step k at ``t[k]``) and its metrics."""

    t: np.ndarray                 # (K,) s
    x: np.ndarray                 # (K, N, 2) m
    tension: np.ndarray           # (K, N+1) N
    elastic: np.ndarray           # (K, N+1) m, elastic elongation e1
    plastic: np.ndarray           # (K, N+1) m, plastic elongation p
    tool: np.ndarray              # (K, 2) m
    tool_force: np.ndarray        # (K, 2) N, sheet on tool
    mould_force: np.ndarray       # (K, N, 2) N, cake + workplane on each mass
    tool_contact: np.ndarray      # (K, N, 2) N, tool on each mass
    rest_length: np.ndarray       # (N+1,) m
    peak: PeakTension
    SF: float
    delta: float                  # m
    wall_time_s: float
    params: CellParams = field(repr=False)
    anchors: tuple = field(repr=False, default=())

    @property
    def F_max(self) -> float:
        return self.peak.value

    def nodes(self, k: int = -1) -> np.ndarray:
        return np.vstack((self.anchors[0], self.x[k], self.anchors[1]))

    @property
    def run_summary(self) -> RunSummary:
        return RunSummary(self.peak.value, self.peak.link, self.peak.time, self.SF, self.delta)

    def summary(self) -> dict:
        """The key figures as plain numbers (SI units)."""
        return {**self.run_summary.as_dict(), "steps": int(self.t.size - 1),
                "wall_time_s": self.wall_time_s}


def _fine_start(dts: np.ndarray, poses: np.ndarray, t0: float, pose0, span: float,
                h: float) -> tuple[np.ndarray, np.ndarray]:
    """Steps ``dts`` (poses at their ends) from ``t0`` with those in the first ``span`` [s]
    cut into pieces of at most ``h`` [s] (poses linear within a step)."""
    out_dt, out_pose = [], []
    t, prev = t0, np.asarray(pose0, float)
    for dt, pose in zip(dts, poses):
        k = int(math.ceil(dt / h - 1e-9)) if t < t0 + span else 1
        for j in range(1, k + 1):
            out_dt.append(dt / k)
            out_pose.append(prev + (pose - prev) * (j / k))
        t, prev = t + dt, pose
    return np.array(out_dt, float), np.array(out_pose, float).reshape(-1, 2)


#: Whole-run step schedules already planned (:func:`_whole_schedule`), by what they depend on.
_SCHEDULES: dict = {}


def _whole_schedule(sim: Simulation, path: ToolPath, knots: list, t_end: float,
                    laid: LaidSheet | None) -> tuple[np.ndarray, np.ndarray]:
    """The steps of a whole run from ``sim``'s state through ``knots`` to ``t_end`` [s]:
    (dt (K,) [s], tool pose at the end of each step (K, 2) [m]), the fall after a ``laid``
    sheet's release cut into inertial steps.  The schedule depends on the tool path, the
    solver's step limits and the start only, never on the sheet: a polyline path's is kept
    (the diagnosis runs the same record's path hundreds of times) and handed out as it is
    (the kernel only reads it)."""
    s0, sp = sim.state, sim.params.solver
    key = None
    if isinstance(path, PolylinePath):
        key = (np.asarray(path.times, float).tobytes(), np.asarray(path.points, float).tobytes(),
               float(t_end), sp.dt, sp.dt_still,
               sp.max_tool_step, float(s0.t), np.asarray(s0.tool, float).tobytes(),
               None if laid is None else (laid.release_time, sp.dt_settle))
        hit = _SCHEDULES.get(key)
        if hit is not None:
            return hit
    parts, t, pose = [], s0.t, s0.tool
    for k in knots:
        dts, poses = sim.schedule(k, path.position(k), path.position, (t, pose))
        parts.append((dts, poses))
        for dt in dts:        # the clock as the steps keep it
            t = t + dt
        if len(dts):
            pose = poses[-1]
    dts = np.concatenate([d for d, _ in parts])
    poses = np.concatenate([q for _, q in parts]).reshape(-1, 2)
    if laid is not None:      # the fall after the release: inertial steps
        dts, poses = _fine_start(dts, poses, s0.t, s0.tool, laid.release_time, sp.dt_settle)
    if key is not None:
        if len(_SCHEDULES) >= 32:
            _SCHEDULES.clear()
        _SCHEDULES[key] = (dts, poses)
    return dts, poses


def run_scenario(params: CellParams, path: ToolPath, t_end: float | None = None,
                 progress: Callable[[float], None] | None = None,
                 laid: LaidSheet | None = None, start: SheetState | None = None) -> RunResult:
    """Run the cell over a tool path from t = 0 to ``t_end`` (default: process time); with
    ``laid`` from its release at ``laid.t0``, with ``start`` from that sheet (Simulation)."""
    t_end = params.movement.process_time if t_end is None else float(t_end)
    t_start = 0.0 if laid is None else float(laid.t0)
    sim = Simulation(params, tool_start=path.position(t_start), laid=laid, start=start)
    s0 = sim.state
    knots = [k for k in np.asarray(path.knots(), float) if s0.t < k < t_end] + [t_end]
    wall = time.perf_counter()
    if progress is None:          # the whole path in one kernel call
        recs = [sim.advance_path(*_whole_schedule(sim, path, knots, t_end, laid))]
    else:
        if laid is not None:
            raise ValueError("run_scenario: a laid sheet runs without a progress callback")
        recs = []
        for k in knots:
            recs.append(sim.advance_record(k, path.position(k), tool_at=path.position))
            progress(sim.state.t)
    wall = time.perf_counter() - wall

    def series(name: str, first) -> np.ndarray:
        return np.concatenate([np.asarray(first)[None]] + [getattr(r, name) for r in recs])

    times = series("t", s0.t)
    tension = series("tension", s0.tension)
    contact = series("contact", s0.contact)
    peak = peak_tension(times, tension)
    return RunResult(
        t=times, x=series("x", s0.x), tension=tension,
        elastic=series("e1", s0.e1), plastic=series("p", s0.p),
        tool=series("tool", s0.tool), tool_force=-contact[:, TOOL].sum(axis=1),
        mould_force=contact[:, CAKE] + contact[:, WORKPLANE], tool_contact=contact[:, TOOL],
        rest_length=sim.constants.rest_length, peak=peak,
        SF=safety_factor(params.material.F_break, peak.value), delta=sim.delta(),
        wall_time_s=wall, params=params,
        anchors=(sim.constants.anchor_top, sim.constants.anchor_bottom))
