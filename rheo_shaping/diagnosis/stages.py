"""The diagnosis's stages before any effect: the nominal runs and noise, the calibrated
baseline, the gap test and the sensor side (:mod:`engine` runs them in order)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..params.schema import ParameterError
from . import replay, stats
from .baseline import CHAIN, SHEET, reference
from .candidates import Explanation
from .compare import RecordData, noise_level
from .context import Baseline, FitContext, Group, forward_jacobian, inward_steps
from .evaluate import Outcome, Runner, Task, all_ok
from .linear import Solver

#: The least noise [m, N] the diagnosis weighs the records' residuals with: the resolution of a
#: fine camera and load cell.  Records without noise (a simulator's own, noise-free streams)
#: show none in their second differences; a weight of zero noise would be infinite, and the
#: 1 N used when a record has no force would ignore a force that is there.
MIN_PROFILE_NOISE = 1e-5
MIN_FORCE_NOISE = 1e-3
#: Step of the baseline's forward differences, in tolerances (tried + then -).
JACOBIAN_STEP = 0.5
#: Times a baseline step that fits worse than the best point so far is halved (the model is
#: not linear over the whole step: seen on a laid sheet at N = 63, a full step to J - 1 of
#: 12.5 from the nominal 1.4).
STEP_HALVINGS = 2
#: Steps the baseline takes on each Jacobian (the linear step, then chord steps), each kept
#: only when it lowers J; the Jacobians it takes at most (each later one at the best point
#: so far, while the last round lowered J - 1 by more than ``BASELINE_CONVERGED`` of it).
BASELINE_STEPS = 2
BASELINE_JACOBIANS = 5
BASELINE_CONVERGED = 0.05


@dataclass(frozen=True)
class Nominal:
    """Stage 1: the written scenario's runs (every record) and the noise levels they show."""

    outs: list[Outcome]
    sp: float                       # m, profile noise
    sf: float                       # N, tool force noise (1 N when the records have none)
    J0: float                       # nominal misfit, fit records
    J0_h: float                     # nominal misfit, holdout records (nan without)


def nominal_stage(data: list[RecordData], nf: int, run: Runner,
                  sheet_lim: float = 1.0) -> tuple[Nominal, FitContext]:
    """Stage 1: the nominal models, the noise (MAD of second differences), the fit context
    (the sheet knobs fitted within +-``sheet_lim`` tolerances; 0: held as written)."""
    run.stage("nominal models", len(data))
    nominal = run([Task(d, reference(d.record.scenario, sheet_lim), keep_run=True)
                   for d in data])
    bad = [d.record.name for d, o in zip(data, nominal) if not o.ok]
    if bad:
        raise ValueError(f"the nominal model of record '{bad[0]}' does not run: "
                         f"{next(o.error for o in nominal if not o.ok)}")
    sp = float(np.nanmedian([noise_level(o.array("profile"), d.point_frame)
                             for d, o in zip(data, nominal)]))
    sfs = [noise_level(o.force[:, k]) for o in nominal if o.force is not None for k in (0, 1)]
    sf = float(np.nanmedian(sfs)) if sfs else math.nan
    if math.isnan(sp):
        raise ValueError("the records' profile noise cannot be estimated "
                         "(too few points per frame)")
    sp = max(sp, MIN_PROFILE_NOISE)
    # no force in the records: 1 N (the force then weighs nothing); noise-free force: the floor
    sf = 1.0 if math.isnan(sf) else max(sf, MIN_FORCE_NOISE)
    fit_d, hold_d = data[:nf], data[nf:]
    G = Group.of(fit_d, sp, sf, nominal[:nf])
    H = Group.of(hold_d, sp, sf, nominal[nf:]) if hold_d else None
    ctx = FitContext(fit_d, hold_d, G, H, run, sp, sf, sheet_lim)
    J0 = G.J(G.z(nominal[:nf]))
    J0h = H.J(H.z(nominal[nf:])) if H else math.nan
    return Nominal(nominal, sp, sf, J0, J0h), ctx


def baseline_stage(ctx: FitContext, nominal: Nominal,
                   A_sheet: np.ndarray | None = None) -> Baseline:
    """The sheet knobs' Jacobian (forward differences of half a tolerance; ``A_sheet``, one
    already measured near this point, when given), a bounded least-squares step on it,
    checked by simulation (halved up to ``STEP_HALVINGS`` times while it fits worse than the
    best point so far), one chord step from there, checked again; then again from a
    Jacobian at the best point while the last round lowered J enough (``BASELINE_JACOBIANS``,
    ``BASELINE_CONVERGED``); the best of the points tried (nominal included) with the chain
    refitted."""
    G, nf, n_s, run = ctx.G, ctx.nf, ctx.n_s, ctx.run
    z0 = G.z(nominal.outs[:nf])

    def stepped_from(u0: np.ndarray) -> Callable[[int, float], list]:
        """The fit records' cells with sheet knob j at ``u0[j] + h`` (tolerances)."""
        return lambda j, h: [ctx.params(d, u0 + h * np.eye(n_s)[j]) for d in ctx.fit_d]

    def invalid(j: int) -> list:
        raise ValueError(f"baseline knob {SHEET[j].name}: no valid step of half a tolerance")
    if A_sheet is None:
        A_sheet = forward_jacobian(ctx, z0, stepped_from(np.zeros(n_s)),
                                   [(JACOBIAN_STEP, -JACOBIAN_STEP)] * n_s,
                                   invalid, announce=lambda n: run.stage("baseline Jacobian", n))
    solver = G.solver(A_sheet)
    chain_lim = ctx.chain_lim
    b = ctx.sheet_lim
    slo, shi = ctx.sheet_lo, ctx.sheet_hi
    chain_solver = Solver(G.chain)

    def tried_point(u_s: np.ndarray, outs: list) -> tuple:
        """(sheet knobs, outcomes, J of the fit records with the chain refitted, the chain's
        knobs) of a point that was run; J is inf if a run failed."""
        if not all_ok(outs[:nf]):
            return u_s, outs, math.inf, None
        u_c, J = chain_solver.solve(G.z(outs[:nf]), -chain_lim, chain_lim)
        return u_s, outs, float(J), u_c

    tried = [tried_point(np.zeros(n_s), nominal.outs)]
    best_u, best_J, best_z = np.zeros(n_s), tried[0][2], z0
    # held knobs (b = 0): the nominal point, already run, is the only point in the box
    # at most: each round's steps and halvings on every record, the later rounds' Jacobians
    run.stage("baseline fit", BASELINE_JACOBIANS * (2 + STEP_HALVINGS) * len(ctx.data)
              + (BASELINE_JACOBIANS - 1) * n_s * nf if b > 0 else 0)
    J_round = tried[0][2]                  # J where the round began
    for rnd in range(BASELINE_JACOBIANS if b > 0 else 1):
        if rnd:
            # the knobs act differently where the last Jacobian's steps went (the contact's
            # stiffness on a log scale, a laid sheet's sag): again from the best point, while
            # the last round lowered the excess J - 1 by more than BASELINE_CONVERGED of it
            if not J_round - best_J > BASELINE_CONVERGED * max(J_round - 1.0, 0.0):
                break
            J_round = best_J
            A_sheet = forward_jacobian(ctx, best_z, stepped_from(best_u.copy()),
                                       inward_steps(best_u, shi, JACOBIAN_STEP), invalid)
            solver = G.solver(A_sheet)
        du0, _ = solver.solve(best_z, np.r_[slo - best_u, -chain_lim],
                              np.r_[shi - best_u, chain_lim])
        u_try, steps, halvings = np.clip(best_u + du0[:n_s], slo, shi), 0, 0
        while steps < BASELINE_STEPS and b > 0:
            try:
                outs = run([Task(d, ctx.params(d, u_try), keep_run=True) for d in ctx.data])
            except ParameterError:
                break
            tried.append(tried_point(u_try, outs))
            J_try = tried[-1][2]
            if not J_try < best_J and halvings < STEP_HALVINGS:
                # the model is not linear that far: half the step from the best point so far
                halvings += 1
                u_try = best_u + 0.5 * (u_try - best_u)
                continue
            if not math.isfinite(J_try):
                break
            zb = G.z(outs[:nf])
            if J_try < best_J:
                best_u, best_J, best_z = u_try, J_try, zb
            steps += 1
            # chord step: same Jacobian from the new point
            du, _ = solver.solve(zb, np.r_[slo - u_try, -chain_lim],
                                 np.r_[shi - u_try, chain_lim])
            u_try = np.clip(u_try + du[:n_s], slo, shi)
    best = None
    for u_try, outs, J, u in tried:
        if not math.isfinite(J) or (ctx.H and not all_ok(outs[nf:])):
            continue
        if best is None or J < best[1]:
            best = (u_try, J, outs, u)
    assert best is not None         # the nominal point is tried, and every nominal run ran
    u_s, J_base, base_outs, u_c = best
    zB_raw = G.z(base_outs[:nf])
    zB = zB_raw + G.chain @ u_c
    H = ctx.H
    J_base_h = H.J_with_chain(H.z(base_outs[nf:]), u_c) if H else math.nan
    return Baseline(u_s, u_c, J_base, J_base_h, base_outs, zB_raw, zB, G.stack.J_parts(zB),
                    G.n_eff(zB), A_sheet, solver, chain_solver)


@dataclass(frozen=True)
class GapTest:
    """Stage 3: the baseline's excess against its calibrated effect-free null."""

    p: float                        # p_gap
    replay: tuple                   # (fit, holdout) draws of the replay misfit, or None each
    below_tolerance: bool = False   # the baseline's remainder is below the user's tolerance

    @property
    def left(self) -> bool:
        """A gap is left for an effect or the chain to explain (and worth naming)."""
        return self.p <= stats.ALPHA and not self.below_tolerance


def gap_stage(ctx: FitContext, base: Baseline) -> GapTest:
    """Stage 3: p_gap; for a cell with a Kelvin dashpot the null plus the model's own replay
    misfit, measured here (:mod:`replay`)."""
    rp: tuple[np.ndarray | None, ...] = (None, None)
    if any(replay.kelvin(d.record.scenario) for d in ctx.data):
        ctx.run.stage("replay misfit (Kelvin cell)", (1 + replay.DRAWS) * len(ctx.data))
        rp = tuple(replay.replay_misfit(dd, [ctx.params(d, base.u_s) for d in dd], ctx.run,
                                        ctx.sp, ctx.sf)
                   if dd else None for dd in (ctx.fit_d, ctx.hold_d))
    return GapTest(stats.gap_p_value(base.J - 1.0, shift=rp[0]), rp)


def outside(u_chain: np.ndarray) -> list[str]:
    """The chain knobs beyond their tolerance (``u_chain`` in tolerances)."""
    return [k.name for k, v in zip(CHAIN, u_chain) if abs(v) > 1.0 + 1e-6]


def sensor_stage(ctx: FitContext, base: Baseline) -> Explanation:
    """Stage 4, which side: the measurement chain's hypothesis (chain beyond its tolerance,
    the sheet knobs refitted; linear, no simulation) and its likelihood ratio against the
    baseline.  Checked by simulation with the effects (:func:`verdict.candidates_stage`)."""
    n_s = ctx.n_s
    free = ctx.chain_free
    u_ch, J_ch = base.solver.solve(base.z_raw, np.r_[ctx.sheet_lo - base.u_s, -free],
                                   np.r_[ctx.sheet_hi - base.u_s, free])
    chain_c = Explanation((), {}, J_ch,
                          ctx.G.stack.J_parts(base.solver.residual(base.z_raw, u_ch)),
                          baseline_u=u_ch, chain_free=True)
    chain_c.k = max(len(outside(u_ch[n_s:])), 1)
    chain_c.LR = stats.likelihood_ratio(base.parts, chain_c.J_parts, base.n_eff)
    return chain_c
