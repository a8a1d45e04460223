"""The diagnosis: a calibrated baseline first, then whether a gap is left, which side of the
sensors, which effect.

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
3. The floor and the gap test.  The baseline's excess misfit against what an
   effect-free record leaves (p_gap): the floor (:mod:`floor`; ``model-form`` by
   default, the dynamic world's effect-free remainders per configuration, or
   ``numerics``, or a calibration file; scaled to the cell by ``reference`` records).
   p_gap > ALPHA, or a remainder below the user's ``tolerance``: ``none``.  For a written
   cell with a Kelvin dashpot the numerics null adds the model's own replay misfit
   (:mod:`replay`).
4. Which side.  The chain's hypothesis: the baseline with the chain free against the
   chain held within its tolerances (:func:`stages.sensor_stage`); a chain value beyond
   its tolerance that explains the gap puts it on the measurement side (a load cell's lag
   only when the profile does not lag too, :mod:`timing`).
5. Which effect.  Each library effect is probed at the baseline (two magnitudes per fit
   record for a scalar effect, both sides of each axis for tool_offset, one run for
   mass_error) and fitted jointly with the baseline's knobs on the linearised model.  The
   effects :func:`converge.to_check` picks (the two best by p, the two of least J, every one
   whose first fit explains at least 15 % of the excess) are checked by simulation on the
   fit and holdout records, and every strong one refined to convergence
   (:func:`converge.converge`).  Named, against the numerics floor: p (Bonferroni over the
   candidates) <= ALPHA and adequate (:func:`adequacy.adequate`); against a model-form
   floor: the naming rule of :mod:`naming` (the lead's remainder, with its prior's cost,
   clearly below the baseline's and every rival's).  Else the pairs among the three best,
   same rule; else ``unexplained``, with the residual's signature and the kinds of cause it
   points to (:mod:`signature`).
6. How far.  Gap figures: nominal, baseline and verdict on fit and holdout
   records (:mod:`gap`).

Every batch of simulations goes through :func:`evaluate.run_batch` on one
executor (``executor=``, default a local process pool on ``jobs`` cores).

Each step is one function over a frozen :class:`~.context.FitContext` (the records, their
groups, the noise, the runner) returning a small frozen result: :mod:`stages` (nominal,
baseline, gap test, sensor side) and :mod:`verdict` (candidate effects, pairs, verdict, the
verdict's runs); :func:`diagnose` calls them in order and assembles the :class:`Diagnosis`.
"""
from __future__ import annotations

import math
from concurrent.futures import Executor
from dataclasses import replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..records.record import Record
from ..sheet.effects import EFFECT_NAMES
from . import floor as fl_mod, intervals, naming as naming_mod, stats
from .baseline import reference
from .compare import RecordData, residuals
from .context import Baseline, FitContext
from .evaluate import Runner, apply
from .initial_state import initial_summary, pool
from .laid_length import laid_lengths
from .figures import FloorReport, Noise
from .options import (DEFAULTS, BaselineMode, FloorKind, InitialMode, baseline_mode_of,
                      floor_of, initial_mode_of)
from .result import Diagnosis, Verdict, as_residuals, baseline_table, chain_correct
from .stages import Nominal, baseline_stage, gap_stage, nominal_stage, sensor_stage
from .verdict import (After, Candidates, VerdictStage, after_stage, candidates_stage,
                      verdict_stage)


def diagnose(records: Sequence[Record], holdout: Sequence[Record] = (),
             library: Sequence[str] = EFFECT_NAMES, jobs: int | None = None,
             progress: Callable[[int], None] | None = None,
             executor: Executor | None = None,
             initial_state: InitialMode | str = DEFAULTS.initial_state,
             floor: FloorKind | str | Path = DEFAULTS.floor, reference: Sequence[Record] = (),
             tolerance: tuple[float, float] | None = None,
             baseline: BaselineMode | str = DEFAULTS.baseline) -> Diagnosis:
    """Diagnose the gap between ``records`` (fitted) and their scenario; check on ``holdout``.

    The switches and their defaults (:data:`.options.DEFAULTS`, the command's too):
    ``initial_state``: how each record's model starts (:class:`.options.InitialMode`:
    ``settled``, the scenario's drape settled before t = 0; ``laid``, the first frame's sheet
    released; ``auto``, the default, laid when the records show the sheet moving before the
    tool touches).  ``floor``: what the gap and the adequacy are judged against
    (:class:`.options.FloorKind`, :mod:`.floor`: ``numerics``, the stored finer-chain null;
    ``model-form``, the default, the dynamic world's calibration for this configuration,
    scaled to ``reference`` records' remainder when given; or a calibration file's path).
    ``tolerance`` (profile [m], tool force [N]): a baseline remainder below both is not
    worth naming (``none``).  ``baseline``:
    ``calibrated`` (the sheet knobs fitted within their tolerances, :mod:`.baseline`) or
    ``held`` (kept as written: the scenario is a cell already calibrated, for one a
    commissioning diagnosis corrected, and the question is what changed since; the gap
    watch's question; :class:`.options.BaselineMode`).  The measurement chain is fitted
    within its tolerances either way."""
    if not records:
        raise ValueError("diagnose needs at least one record to fit")
    initial_state = initial_mode_of(initial_state)
    floor = floor_of(floor)
    baseline = baseline_mode_of(baseline)
    sheet_lim = 1.0 if baseline is BaselineMode.CALIBRATED else 0.0
    scale = (1.0, 1.0)
    if reference:
        if len(reference) < 2:
            raise ValueError("--reference needs at least two effect-free records (one is "
                             "held out)")
        ref = diagnose(reference[:-1], reference[-1:], library=(), jobs=jobs,
                       executor=executor, initial_state=initial_state,
                       floor=FloorKind.NUMERICS, baseline=baseline)
        path = floor if isinstance(floor, Path) else fl_mod.FLOOR_FILE
        scale = fl_mod.reference_scale(ref, reference[0].scenario.sheet.n_masses,
                                       float(round(max(r.duration for r in reference))), path)
    library = tuple(library)
    data = [RecordData.of(r, initial_state) for r in list(records) + list(holdout)]
    read = pool([d.initial for d in data], initial_state == "auto")
    nf = len(records)
    with stats.using_null(None), Runner(executor, jobs, progress) as run:
        start = _start([replace(d, initial=s) for d, s in zip(data, read)], nf, run, sheet_lim)
        data, nominal, ctx, base = start
        choice = None
        if initial_state == "auto" and all(s is not None and s.mode == "settled"
                                           for s in read):
            # read as settled: the sheet hardly moved before the tool touched, which a sheet
            # laid close to its resting shape does too; the start whose baseline fits the
            # fit records better is taken (docs/diagnosis.md, Initial state)
            run.stage("the laid start, to compare")
            as_laid = [None if s is None else replace(s, mode="laid") for s in read]
            laid = _start([replace(d, initial=s) for d, s in zip(data, as_laid)], nf, run,
                          sheet_lim)
            choice = {"settled_J": start[3].J, "laid_J": laid[3].J}
            if laid[3].J < start[3].J:
                data, nominal, ctx, base = laid
        fl = _floor((floor, scale, bool(reference)), data, ctx.nf, len(ctx.hold_d), ctx.sp,
                    ctx.sf)
        stats.using_null_now(fl.sample)              # the gap test and adequacy use it
        gap = gap_stage(ctx, base)
        below = fl_mod.within_tolerance(base.parts, ctx.sp, ctx.sf, tolerance)
        gap = replace(gap, below_tolerance=below)
        chain_c = sensor_stage(ctx, base)
        cands = candidates_stage(ctx, base, gap, chain_c, library)

        judged: dict[int, naming_mod.Naming] = {}   # id(explanation) -> naming.judge's
        level = fl.level()

        def naming_of(c) -> naming_mod.Naming:
            if id(c) not in judged:
                judged[id(c)] = naming_mod.judge(c, cands.effects, base.J, base.J_h,
                                                 bool(ctx.hold_d), level)
            return judged[id(c)]

        def clear(c) -> bool:
            """Most of the excess on fit and holdout records, clearly the best."""
            return naming_of(c).named
        rule = None if fl.source == "numerics" else clear
        verdict = verdict_stage(ctx, base, gap, chain_c, cands, library, rule)
        named = verdict.fit or (chain_c if verdict.chain_side else None)
        naming = naming_of(named) if rule is not None and named is not None else None
        after = after_stage(ctx, base, verdict, chain_c)
        runs = run.runs
    floor_rep = _floor_report(fl, base, named, naming, below, tolerance, ctx.sp, ctx.sf,
                              cands.responses, ctx.G)
    return _assemble(ctx, nominal, base, gap.p, gap.replay, cands, verdict, after, runs,
                     floor=floor_rep, initial_state=initial_summary(data, choice),
                     baseline_mode=baseline)


def _start(data: list, nf: int, run: Runner, sheet_lim: float) -> tuple:
    """Stages 1-2 from ``data``'s initial states: each laid record's rest length, the nominal
    models and the baseline; with laid records, their lengths again with the calibrated cell
    (its bonds and sag move them) and the baseline from there on the same Jacobian.
    Returns (data, nominal, fit context, baseline)."""
    data = laid_lengths(data, [reference(d.record.scenario, sheet_lim) for d in data], run)
    nominal, ctx = nominal_stage(data, nf, run, sheet_lim)
    base = baseline_stage(ctx, nominal)
    if any(d.initial is not None and d.initial.mode == "laid" for d in data):
        run.stage("laid lengths and baseline again")
        data = laid_lengths(data, [ctx.params(d, base.u_s) for d in data], run)
        nominal, ctx = nominal_stage(data, nf, run, sheet_lim)
        base = baseline_stage(ctx, nominal, base.A_sheet)
    return data, nominal, ctx, base


def _floor(spec, data, nf: int, nh: int, sp: float, sf: float) -> "fl_mod.Floor":
    """The floor this diagnosis is judged against (``spec``: (kind or file, reference
    scale, from reference records))."""
    kind, scale, from_ref = spec
    if kind is FloorKind.NUMERICS:
        return fl_mod.numerics_floor()
    path = kind if isinstance(kind, Path) else fl_mod.FLOOR_FILE
    sc = data[0].record.scenario
    T = float(round(max(d.record.duration for d in data)))
    src = (f"reference records (the stored dynamic-world floor scaled by {scale[0]:.2f} in "
           f"profile, {scale[1]:.2f} in force)" if from_ref else None)
    return fl_mod.stored_floor(sc.sheet.n_masses, T, nf, nh, sp, sf, path, scale, src)


def _floor_report(floor, base: Baseline, verdict_fit, naming, below_tol: bool, tolerance,
                  sp: float, sf: float, responses, G=None) -> FloorReport:
    """The floor, what the baseline and the verdict leave against it, and the model-form
    part of the verdict's interval: estimated from the fit records' remainder
    (:mod:`.intervals`); the worst-case bound of a floor-sized discrepancy is reported beside
    it, and widens the interval only where no remainder is at hand."""
    q_h = floor.quantile(True)
    out: dict = {}
    if verdict_fit is not None:
        out["verdict"] = fl_mod.remainder(verdict_fit.J, verdict_fit.J_parts, sp, sf, floor)
        if math.isfinite(verdict_fit.J_holdout):
            out["verdict_holdout"] = fl_mod.holdout_remainder(verdict_fit.J_holdout, floor)
        if floor.source != "numerics" and responses:
            # the worst case: a discrepancy of the floor's size, or of what the named effect
            # leaves on the fit records when that is beyond the floor, along the response
            q = fl_mod.discrepancy_size(floor.quantile(), verdict_fit.J)
            bounded = replace(verdict_fit, interval=dict(verdict_fit.interval))
            bound = fl_mod.model_form_interval(bounded, q, base.solver.A, responses)
            est = (intervals.remainder_interval(verdict_fit, base.solver.A, responses, G.data,
                                                G.stack) if G is not None else None)
            if est is None:
                verdict_fit.interval.update(bounded.interval)
                out["model_form_interval_width"] = bound
            else:
                out["model_form_interval_width"] = est[0]
                out["model_form_spread"] = est[1].as_json()
            out["model_form_discrepancy"] = q
            if bound:
                name = bounded.names[0]
                out["model_form_bound"] = {"width": bound, "interval": [
                    list(iv) for iv in bounded.interval.get(name, [])]}
    return FloorReport(
        source=floor.source, config=floor.config, cases=int(floor.fit.size),
        q95_fit=floor.quantile(), q95_holdout=q_h, q95_profile_m=floor.profile_sys_m,
        q95_force_N=floor.force_sys_N, level=floor.level(),
        baseline=fl_mod.remainder(base.J, base.parts, sp, sf, floor),
        baseline_holdout=(fl_mod.holdout_remainder(base.J_h, floor)
                          if math.isfinite(base.J_h) else None),
        below_tolerance=below_tol, tolerance=tolerance, naming=naming, **out)


def _assemble(ctx: FitContext, nominal: Nominal, base: Baseline, p_gap: float, rp: tuple,
              cands: Candidates, verdict: VerdictStage, after: After, runs: int,
              **rest) -> Diagnosis:
    """The :class:`Diagnosis` of the stages' results: gap figures, where, the signature
    (``rest``: its floor, initial states and baseline mode)."""
    from . import gap, where as where_mod
    from .signature import describe, partial_shares
    data, fit_d, hold_d, nf, n_s = ctx.data, ctx.fit_d, ctx.hold_d, ctx.nf, ctx.n_s
    sp, sf = ctx.sp, ctx.sf
    vfc = after.fit
    corrected = (apply(ctx.params(fit_d[0], vfc.fitted_u[:n_s]), vfc.candidate)
                 if vfc else ctx.params(fit_d[0], base.u_s))
    baseline_tab = baseline_table(fit_d[0].record.scenario,
                                  vfc.fitted_u if vfc else np.r_[base.u_s, base.u_c],
                                  ctx.sheet_lim)
    nom_res = [residuals(d, o.kept_run) for d, o in zip(data, nominal.outs)]
    base_runs = [o.run for o in base.outs]
    base_res = [chain_correct(residuals(d, o.kept_run), o, base.u_c)
                for d, o in zip(data, base.outs)]
    after_res = ([chain_correct(as_residuals(d, o, base_runs[i]), o, after.u_c) for i, (d, o) in
                  enumerate(zip(data, after.outs))] if vfc else base_res)
    fit_idx, hold_idx = tuple(range(nf)), tuple(range(nf, len(data)))
    before = gap.figures(data, nom_res, fit_idx, hold_idx, sp, sf)
    signature = None
    if verdict.name not in ("none", "measurement chain"):
        signature = describe(fit_d, base_res[:nf], base_runs[:nf], sp, sf, base.u_c,
                             partial_shares(cands.effects, base.J))
    named = tuple(verdict.fit.names) if verdict.fit is not None else ()
    kind = (Verdict.PAIR if len(named) > 1 else Verdict.EFFECT) if named else \
        Verdict(verdict.name)
    return Diagnosis(
        verdict=kind, named=named, verdict_fit=verdict.fit, effects=cands.effects,
        pairs=verdict.pairs, where=where_mod.rank(fit_d, base_res[:nf], base_runs[:nf], sp, sf),
        gap_before=before,
        gap_baseline=gap.figures(data, base_res, fit_idx, hold_idx, sp, sf, before=before),
        gap_after=gap.figures(data, after_res, fit_idx, hold_idx, sp, sf, before=before),
        noise=Noise(profile_m=sp, force_N=sf), J0=nominal.J0, J0_holdout=nominal.J0_h,
        J_base=base.J, J_base_holdout=base.J_h, baseline=baseline_tab, side=verdict.side,
        p_gap=p_gap, n_eff=base.n_eff, records=[d.record.name for d in fit_d],
        holdout=[d.record.name for d in hold_d], runs=runs, signature=signature,
        corrected=corrected, numerics_base=cands.base_c, J_replay=rp,
        residual_maps=[(d, nom_res[i], after_res[i], nominal.outs[i].run)
                       for i, d in enumerate(data)], **rest)
