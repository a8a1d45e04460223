"""The diagnosis: a calibrated baseline first, then which side of the sensors, then which effect.

1. Noise.  s_p [m] and s_f [N] from the nominal residuals (MAD of second
   differences, :func:`compare.noise_level`).
2. Baseline (:mod:`baseline`).  The written scenario's uncertain values (the
   sheet knobs: material within its identification interval, mass per length,
   bonds, initial sag, cake geometry) and the measurement chain (vision
   offset, load cell bias, gain, lag) are fitted to the fit records: one
   simulation per sheet knob and fit record gives the Jacobian (forward
   difference of half a tolerance), the chain's columns are linear in the
   residuals; a bounded least-squares step on the balanced misfit, checked by
   simulation, then one chord step (same Jacobian) checked again; the better
   is the baseline.  The verdict is about what this baseline cannot explain.
3. Which side.  The chain's part: the baseline with the chain free against
   the chain held within its tolerances (likelihood ratio, :mod:`stats`); a
   chain value beyond its tolerance with p <= ALPHA puts (part of) the gap on
   the measurement side, reported before any effect of the sheet.
4. Gap test.  The baseline's excess misfit against its calibrated
   effect-free distribution (p_gap).  p_gap > ALPHA: ``none``.  For a written
   cell with a Kelvin dashpot that distribution is the stored one plus the
   model's own replay misfit, measured here (:mod:`replay`).
5. Which effect.  Each library effect is probed at the baseline by two
   simulations per fit record (one per axis for tool_offset, one for
   mass_error, both linear) and fitted jointly with the baseline's knobs on
   the linearised model (piecewise linear in the effect's magnitude); the two
   best (by their likelihood-ratio p-value) are checked by simulation on the
   fit and holdout records.  Named: p (Bonferroni over the candidates) <=
   ALPHA, and what it leaves is adequate (:func:`check.adequate`: excess
   within the effect-free null's 95 % quantile on fit and holdout records,
   plus the model's own discretisation error at the candidate, measured by
   re-running it refined, :func:`check.numerics`; and the holdout improves).
   Else the pairs among the three best (linearised, the best checked by
   simulation), same rule; else ``unexplained``, with the residual's
   signature and the kinds of cause it points to (:mod:`signature`).
6. How far.  Gap figures: nominal, baseline and verdict on fit and holdout
   records (:mod:`gap`).

Every batch of simulations goes through :func:`evaluate.run_batch` on one
executor (``executor=``, default a local process pool on ``jobs`` cores).
"""
from __future__ import annotations

import math
from concurrent.futures import Executor
from dataclasses import replace
from typing import Callable, Sequence

import numpy as np

from ..sheet.effects import EFFECT_NAMES
from ..params.params import CellParams
from ..records.record import Record
from ..params.schema import ParameterError
from . import floor as fl_mod, replay, stats
from .initial_state import initial_summary, pool
from .baseline import CHAIN, SHEET, with_sheet
from .candidates import (CHECKED, PAIRED, PROBES, REFINE_STEPS, Explanation, fit_pair,
                         fit_single, rank_key)
from .check import (adequate, check, needs_numerics, numerics, refine_points,
                    relinearise)
from .compare import RecordData, noise_level, residuals
from .evaluate import Outcome, Runner, Task, all_ok, apply
from .linear import Solver, Stack
from .result import Diagnosis, as_residuals, baseline_table, chain_correct, num as _num


class _Group:
    """The records of one group (fit or holdout) and their stacked residuals."""

    def __init__(self, data: list[RecordData], sp: float, sf: float, nominal: list[Outcome]):
        self.data = data
        self.stack = Stack([d.point_frame for d in data], [d.record.has_wrench for d in data],
                           sp, sf)
        self.stack.set_force_count(nominal)
        self.chain = self.stack.chain_columns(nominal) if data else np.zeros((0, len(CHAIN)))
        self._solvers: dict = {}

    def z(self, outs: list[Outcome]) -> np.ndarray:
        return self.stack.vec(outs)

    def solver(self, A_sheet: np.ndarray) -> Solver:
        """The bounded fit on [A_sheet, chain columns]: its QR once per Jacobian (the
        baseline's, or a candidate's own, :func:`check.relinearise`)."""
        hit = self._solvers.get(id(A_sheet))
        if hit is None or hit[0] is not A_sheet:       # the array kept: its id stays its own
            hit = self._solvers[id(A_sheet)] = (A_sheet,
                                                Solver(np.hstack((A_sheet, self.chain))))
        return hit[1]

    def J(self, z: np.ndarray) -> float:
        return float(z @ z)


#: The diagnosis's stages, in order (a progress display shows "stage k of n"); a stage
#: that has nothing to run (the replay misfit of a Maxwell cell, the effects when no gap
#: is left) is passed over.
STAGES = ("nominal models", "baseline Jacobian", "baseline fit",
          "replay misfit (Kelvin cell)", "effect probes", "candidate checks", "verdict runs")


def diagnose(records: Sequence[Record], holdout: Sequence[Record] = (),
             library: Sequence[str] = EFFECT_NAMES, jobs: int | None = None,
             progress: Callable[[int], None] | None = None,
             executor: Executor | None = None, initial_state: str = "settled",
             floor: str = "numerics", reference: Sequence[Record] = (),
             tolerance: tuple[float, float] | None = None) -> Diagnosis:
    """Diagnose the gap between ``records`` (fitted) and their scenario; check on ``holdout``.

    ``initial_state``: how each record's model starts (:mod:`.initial_state`: ``settled``,
    the scenario's drape settled before t = 0; ``laid``, the first frame's sheet released;
    ``auto``, laid when the records show the sheet moving before the tool touches).
    ``floor``: what the gap and the adequacy are judged against (:mod:`.floor`:
    ``numerics``, the stored finer-chain null; ``model-form``, the dynamic world's
    calibration for this configuration, scaled to ``reference`` records' remainder when
    given; or a calibration file's path).  ``tolerance`` (profile [m], tool force [N]): a
    baseline remainder below both is not worth naming (``none``)."""
    if floor not in fl_mod.KINDS and not str(floor).endswith(".json"):
        raise ValueError(f"floor {floor!r}: expected one of {', '.join(fl_mod.KINDS)} or a "
                         "calibration file (.json)")
    scale = (1.0, 1.0)
    if reference:
        if len(reference) < 2:
            raise ValueError("--reference needs at least two effect-free records (one is "
                             "held out)")
        ref = diagnose(reference[:-1], reference[-1:], library=(), jobs=jobs,
                       executor=executor, initial_state=initial_state)
        sc = reference[0].scenario
        path = floor if str(floor).endswith(".json") else fl_mod.FLOOR_FILE
        scale = fl_mod.reference_scale(ref, sc.sheet.n_masses,
                                       float(round(max(r.duration for r in reference))), path)
    with stats.using_null(None):
        return _diagnose(records, holdout, library, jobs, progress, executor, initial_state,
                         (floor, scale, bool(reference)), tolerance)


def _diagnose(records, holdout, library, jobs, progress, executor, initial_state, floor_spec,
              tolerance) -> Diagnosis:
    from . import gap, where as where_mod
    from .signature import describe, partial_shares
    if not records:
        raise ValueError("diagnose needs at least one record to fit")
    library = tuple(library)
    data = [RecordData.of(r, initial_state) for r in list(records) + list(holdout)]
    data = [replace(d, initial=s) for d, s in zip(data, pool(
        [d.initial for d in data], initial_state == "auto"))]
    nf = len(records)
    fit_d, hold_d = data[:nf], data[nf:]
    with Runner(executor, jobs, progress) as run:
        # 1. nominal: noise
        run.stage(1, len(data))
        nominal = run([Task(d, d.record.scenario, keep_run=True) for d in data])
        bad = [d.record.name for d, o in zip(data, nominal) if not o.ok]
        if bad:
            raise ValueError(f"the nominal model of record '{bad[0]}' does not run: "
                             f"{next(o.error for o in nominal if not o.ok)}")
        sp = float(np.nanmedian([noise_level(o.profile, d.point_frame)
                                 for d, o in zip(data, nominal)]))
        sfs = [noise_level(o.force[:, k]) for o in nominal if o.force is not None for k in (0, 1)]
        sf = float(np.nanmedian(sfs)) if sfs else math.nan
        if not (sp > 0):
            raise ValueError("the records' profile noise cannot be estimated "
                             "(too few points per frame)")
        sf = sf if sf > 0 else 1.0
        floor = _floor(floor_spec, data, nf, len(hold_d), sp, sf)
        stats.using_null_now(floor.sample)
        G = _Group(fit_d, sp, sf, nominal[:nf])
        H = _Group(hold_d, sp, sf, nominal[nf:]) if hold_d else None
        z0 = G.z(nominal[:nf])
        J0 = G.J(z0)
        J0h = H.J(H.z(nominal[nf:])) if H else math.nan

        # 2. baseline: Jacobian of the sheet knobs (half a tolerance), chain columns linear
        h = 0.5
        steps, tasks = [], []
        for knob in SHEET:
            for sgn in (1.0, -1.0):
                try:
                    ps = [with_sheet(d.record.scenario, {knob.name: sgn * h}) for d in fit_d]
                except ParameterError:
                    continue
                steps.append(sgn * h)
                tasks += [Task(d, p) for d, p in zip(fit_d, ps)]
                break
            else:
                raise ValueError(f"baseline knob {knob.name}: no valid step of half a tolerance")
        run.stage(2, len(tasks))
        outs = run(tasks)
        cols = []
        for j in range(len(SHEET)):
            o = outs[j * nf:(j + 1) * nf]
            cols.append((G.z(o) - z0) / steps[j] if all_ok(o) else np.zeros_like(z0))
        A_sheet = np.column_stack(cols)
        solver = G.solver(A_sheet)
        A = solver.A
        n_s = len(SHEET)
        chain_lim = np.ones(len(CHAIN))                      # the baseline: within tolerance
        chain_free = np.array([k.limit for k in CHAIN])      # the chain hypothesis: beyond it
        lo = np.r_[-np.ones(n_s), -chain_lim]
        hi = np.r_[np.ones(n_s), chain_lim]

        def base_params(d: RecordData, u_s: np.ndarray) -> CellParams:
            return with_sheet(d.record.scenario, {k.name: float(v) for k, v in zip(SHEET, u_s)})

        chain_solver = Solver(G.chain)

        def chain_fit(z: np.ndarray, chain_lo=-chain_lim, chain_hi=chain_lim):
            """Chain values for residual ``z`` (sheet held): (u_chain, J, corrected z)."""
            u, J = chain_solver.solve(z, chain_lo, chain_hi)
            return u, J, z + G.chain @ u

        u_lin, _ = solver.solve(z0, lo, hi)
        best = None
        u_s = np.zeros(n_s)
        tried = [(np.zeros(n_s), nominal)]
        run.stage(3, 2 * len(data))
        for _it in range(2):
            u_try = np.clip(u_lin[:n_s], -1, 1)
            try:
                outs = run([Task(d, base_params(d, u_try), keep_run=True) for d in data])
            except ParameterError:
                break
            tried.append((u_try, outs))
            if not all_ok(outs[:nf]):
                break
            zb = G.z(outs[:nf])
            # chord step: same Jacobian from the new point
            du, _ = solver.solve(zb, np.r_[-1 - u_try, -chain_lim], np.r_[1 - u_try, chain_lim])
            u_lin = np.r_[u_try + du[:n_s], du[n_s:]]
        for u_try, outs in tried:
            if not all_ok(outs[:nf]) or (H and not all_ok(outs[nf:])):
                continue
            uc, J, zc = chain_fit(G.z(outs[:nf]))
            if best is None or J < best[1]:
                best = (u_try, J, outs, uc)
        u_s, J_base, base_outs, u_c = best
        zB_raw = G.z(base_outs[:nf])
        zB = zB_raw + G.chain @ u_c
        zBh = (H.z(base_outs[nf:]) + H.chain @ u_c) if H else None
        J_base_h = H.J(zBh) if H else math.nan
        parts_B = G.stack.J_parts(zB)
        n_eff = _n_eff(G, zB, fit_d)

        # 3. gap test; for a Kelvin cell the null plus the model's own replay misfit
        rp = (None, None)
        if any(replay.kelvin(d.record.scenario) for d in data):
            run.stage(4, (1 + replay.DRAWS) * len(data))
            rp = tuple(replay.replay_misfit(dd, [base_params(d, u_s) for d in dd], run, sp, sf)
                       if dd else None for dd in (fit_d, hold_d))
        p_gap = stats.gap_p_value(J_base - 1.0, shift=rp[0])
        below_tol = fl_mod.within_tolerance(parts_B, sp, sf, tolerance)
        gap_left = p_gap <= stats.ALPHA and not below_tol

        # 4. which side: the chain beyond its tolerance (no simulation: linear), checked
        u_ch, J_ch = solver.solve(zB_raw, np.r_[-1 - u_s, -chain_free], np.r_[1 - u_s, chain_free])
        chain_c = Explanation((), {}, J_ch, G.stack.J_parts(solver.residual(zB_raw, u_ch)),
                              baseline_u=u_ch, chain_free=True)
        outside = [k.name for k, v in zip(CHAIN, u_ch[n_s:]) if abs(v) > 1.0 + 1e-6]
        chain_c.k = max(len(outside), 1)
        chain_c.LR = stats.likelihood_ratio(parts_B, chain_c.J_parts, n_eff)

        # 5. effects: probes at the baseline, linearised fits
        base_c = None
        effects: list[Explanation] = []
        pairs: list[Explanation] = []
        responses: dict = {}
        if gap_left and library:
            ptasks, index = [], []
            for name in library:
                kind, vals, _ = PROBES[name]
                for v in vals:
                    vv = v if isinstance(v, tuple) else (v,)
                    for d in fit_d:
                        ptasks.append(Task(d, apply(base_params(d, u_s), ((name, vv),))))
                    index.append((name, vv))
            run.stage(5, len(ptasks))
            pouts = run(ptasks)
            for i, (name, vv) in enumerate(index):
                o = pouts[i * nf:(i + 1) * nf]
                responses.setdefault(name, []).append(
                    (vv, G.z(o) - zB_raw if all_ok(o) else None))
            blo = np.r_[-1 - u_s, -chain_lim]
            bhi = np.r_[1 - u_s, chain_lim]
            for name in library:
                c = fit_single(name, responses[name], zB_raw, solver, blo, bhi, G, n_eff,
                               parts_B)
                if c is not None:
                    effects.append(c)
            m = len(effects) + math.comb(min(PAIRED, len(effects)), 2)
            for c in effects:
                c.p = min(1.0, stats.chi2_sf(c.LR, c.k) * m)
            effects.sort(key=lambda c: (c.p, c.J))
            chain_c.p = min(1.0, stats.chi2_sf(chain_c.LR, chain_c.k) * (m + 1))
            run.stage(6)
            check(effects[:CHECKED] + [chain_c], run, fit_d, hold_d, G, H, u_s, n_s, base_params,
                  chain_fit, parts_B, n_eff, J_base_h, m, chain_free,
                  (A_sheet, responses, REFINE_STEPS))
            base_c = Explanation((), {}, J_base, checked=True, baseline_u=np.r_[u_s, u_c],
                                 z_raw=zB_raw, zh_raw=H.z(base_outs[nf:]) if H else None)
            need = [c for c in effects[:CHECKED] if needs_numerics(c, J_base_h, bool(hold_d), rp)]
            if need:
                # a strong effect changes how the knobs act: refit from its own Jacobian
                relinearise(need, run, fit_d, G, base_params, n_s)
                refine_points(need, run, fit_d, hold_d, G, H, n_s, base_params, chain_fit,
                              parts_B, n_eff, m, chain_free, A_sheet, responses, REFINE_STEPS)
                need = [c for c in need if needs_numerics(c, J_base_h, bool(hold_d), rp)]
            if need:
                numerics(need + [base_c], run, fit_d, hold_d, G, H, base_params, n_s, A,
                         responses)
        elif gap_left:
            run.stage(6)
            check([chain_c], run, fit_d, hold_d, G, H, u_s, n_s, base_params, chain_fit,
                  parts_B, n_eff, J_base_h, 1, chain_free)
        # decision
        verdict_fit = None
        if not gap_left or not library:
            chain_c.p = min(1.0, stats.chi2_sf(chain_c.LR, chain_c.k))
        outside = [k.name for k, v in zip(CHAIN, chain_c.baseline_u[n_s:]) if abs(v) > 1.0 + 1e-6]
        chain_c.adequate = chain_c.checked and adequate(chain_c, J_base_h, bool(hold_d), replay=rp)
        chain_ok = gap_left and chain_c.checked and chain_c.p <= stats.ALPHA and chain_c.adequate
        for c in effects:
            c.adequate = c.checked and adequate(c, J_base_h, bool(hold_d), base_c, rp)
        ranked = sorted(effects, key=rank_key)
        if gap_left and ranked:
            lead = ranked[0]
            if lead.checked and lead.p <= stats.ALPHA and lead.adequate and not (
                    chain_ok and chain_c.J < lead.J):
                verdict_fit = lead
            elif chain_ok:
                pass
            elif len(effects) >= 2:
                top = sorted(effects, key=lambda c: (c.p, c.J))[:PAIRED]
                for i, a in enumerate(top):
                    for b in top[i + 1:]:
                        pc = fit_pair(a, b, responses, zB_raw, solver,
                                      np.r_[-1 - u_s, -chain_lim],
                                      np.r_[1 - u_s, chain_lim], G, n_eff, parts_B)
                        if pc is not None:
                            pc.p = min(1.0, stats.chi2_sf(pc.LR, pc.k) * m)
                            pairs.append(pc)
                pairs.sort(key=lambda c: (c.p, c.J))
                if pairs:
                    check(pairs[:1], run, fit_d, hold_d, G, H, u_s, n_s, base_params, chain_fit,
                          parts_B, n_eff, J_base_h, m, chain_free,
                          (A_sheet, responses, REFINE_STEPS))
                    if needs_numerics(pairs[0], J_base_h, bool(hold_d), rp):
                        # the baseline again, refined the same way as the pair
                        numerics([pairs[0], base_c], run, fit_d, hold_d, G, H, base_params,
                                 n_s, A, responses)
                    bp = pairs[0]
                    bp.adequate = bp.checked and adequate(bp, J_base_h, bool(hold_d), base_c, rp)
                    # a pair must beat each of its parts significantly
                    if bp.checked and bp.p <= stats.ALPHA and bp.adequate:
                        verdict_fit = bp
        if (verdict_fit is not None and verdict_fit.J_parts and chain_ok
                and chain_c.J < verdict_fit.J):
            verdict_fit = None
        naming = None
        if verdict_fit is not None and floor.source != "numerics":
            # beyond the floor: most of the excess on fit and holdout, clearly the best
            naming = fl_mod.clear_name(verdict_fit, effects, J_base, J_base_h, bool(hold_d))
            if not (naming["most"] and naming["clear"]):
                verdict_fit = None
        chain_side = chain_ok and verdict_fit is None
        verdict = ("none" if not gap_left else "+".join(verdict_fit.names) if verdict_fit
                   else "measurement chain" if chain_side else "unexplained")
        side = {"side": ("measurement chain" if chain_side else "sheet" if gap_left
                         else "neither"),
                "chain_outside": outside if chain_side else [],
                "chain_candidate": {"J": chain_c.J, "J_holdout": _num(chain_c.J_holdout),
                                    "p": _num(chain_c.p), "adequate": chain_c.adequate,
                                    "outside": outside,
                                    "values": {k.name: float(v * k.tolerance) for k, v in
                                               zip(CHAIN, chain_c.baseline_u[n_s:])}},
                "p_gap": p_gap}

        # 6. the verdict's runs for the gap figures
        if chain_side:
            verdict_fit_chain = chain_c
        else:
            verdict_fit_chain = None
        if verdict_fit is not None or verdict_fit_chain is not None:
            u_v = (verdict_fit or verdict_fit_chain).baseline_u
            cand = verdict_fit.candidate if verdict_fit else ()
            run.stage(7, len(data))
            after = run([Task(d, apply(base_params(d, u_v[:n_s]), cand)) for d in data])
            u_cv = u_v[n_s:]
        else:
            after, u_cv = base_outs, u_c
        runs = run.runs

    vfc = verdict_fit or verdict_fit_chain
    corrected = (apply(base_params(fit_d[0], vfc.baseline_u[:n_s]), vfc.candidate)
                 if vfc else base_params(fit_d[0], u_s))
    baseline_tab = baseline_table(fit_d[0].record.scenario,
                                  vfc.baseline_u if vfc else np.r_[u_s, u_c])
    nom_res = [residuals(d, o.run) for d, o in zip(data, nominal)]
    base_runs = [o.run for o in base_outs]
    base_res = [chain_correct(residuals(d, o.run), o, u_c) for d, o in zip(data, base_outs)]
    after_res = ([chain_correct(as_residuals(d, o, base_runs[i]), o, u_cv) for i, (d, o) in
                  enumerate(zip(data, after))] if vfc else base_res)
    fit_idx, hold_idx = tuple(range(nf)), tuple(range(nf, len(data)))
    diag = Diagnosis(verdict, verdict_fit, effects, pairs, [], {}, {}, {},
                     {"profile_m": sp, "force_N": sf}, J0, J0h, J_base, J_base_h, baseline_tab,
                     side, p_gap, n_eff, [d.record.name for d in fit_d],
                     [d.record.name for d in hold_d], runs, corrected=corrected,
                     numerics_base=base_c, J_replay=rp)
    diag.initial_state = initial_summary(data)
    diag.floor = _floor_report(floor, diag, verdict_fit, naming, below_tol, tolerance, sp, sf,
                               A, responses, parts_B)
    diag.where = where_mod.rank(fit_d, base_res[:nf], base_runs[:nf], sp, sf)
    diag.gap_before = gap.figures(data, nom_res, fit_idx, hold_idx, sp, sf)
    before = diag.gap_before
    diag.gap_baseline = gap.figures(data, base_res, fit_idx, hold_idx, sp, sf, before=before)
    diag.gap_after = gap.figures(data, after_res, fit_idx, hold_idx, sp, sf, before=before)
    if verdict not in ("none", "measurement chain"):
        diag.signature = describe(fit_d, base_res[:nf], base_runs[:nf], sp, sf, u_c,
                                  partial_shares(effects, J_base))
    diag.residual_maps = [(d, nom_res[i], after_res[i], nominal[i].run)
                          for i, d in enumerate(data)]
    return diag


def _n_eff(G: _Group, z: np.ndarray, data: list[RecordData]) -> dict:
    st = G.stack
    prof = z[:st.n_p]
    frames = np.concatenate([d.point_frame + 100000 * i for i, d in enumerate(data)])
    out = {"profile": stats.n_eff_profile(prof, frames)}
    if st.n_f:
        out["tool force"] = stats.n_eff_force(z[st.n_p:].reshape(-1, 2))
    return out


def _floor(spec, data, nf: int, nh: int, sp: float, sf: float) -> "fl_mod.Floor":
    """The floor this diagnosis is judged against (``spec``: (kind or file, reference
    scale, from reference records))."""
    kind, scale, from_ref = spec
    if kind == "numerics":
        return fl_mod.numerics_floor()
    path = kind if str(kind).endswith(".json") else fl_mod.FLOOR_FILE
    sc = data[0].record.scenario
    T = float(round(max(d.record.duration for d in data)))
    src = (f"reference records (the stored dynamic-world floor scaled by {scale[0]:.2f} in "
           f"profile, {scale[1]:.2f} in force)" if from_ref else None)
    return fl_mod.stored_floor(sc.sheet.n_masses, T, nf, nh, sp, sf, path, scale, src)


def _floor_report(floor, diag: Diagnosis, verdict_fit, naming, below_tol: bool, tolerance,
                  sp: float, sf: float, A, responses, parts_B: dict) -> dict:
    """The floor, what the baseline and the verdict leave against it, and the model-form
    part of the verdict's interval."""
    out = floor.as_dict()
    out["baseline"] = fl_mod.remainder(diag.J_base, parts_B, sp, sf, floor)
    if math.isfinite(diag.J_base_holdout):
        out["baseline_holdout"] = {"J_minus_1": diag.J_base_holdout - 1.0,
                                   "floor_q95": floor.quantile(True),
                                   "beyond_floor": bool(diag.J_base_holdout - 1.0
                                                        > floor.quantile(True))}
    out["below_tolerance"] = below_tol
    out["tolerance"] = None if tolerance is None else {"profile_m": tolerance[0],
                                                       "force_N": tolerance[1]}
    out["naming"] = naming
    if verdict_fit is not None:
        out["verdict"] = fl_mod.remainder(verdict_fit.J, verdict_fit.J_parts, sp, sf, floor)
        if math.isfinite(verdict_fit.J_holdout):
            out["verdict_holdout"] = {"J_minus_1": verdict_fit.J_holdout - 1.0,
                                      "floor_q95": floor.quantile(True),
                                      "beyond_floor": bool(verdict_fit.J_holdout - 1.0
                                                           > floor.quantile(True))}
        if floor.source != "numerics" and responses:
            out["model_form_interval_width"] = fl_mod.model_form_interval(
                verdict_fit, floor.quantile(), A, responses)
    return out
