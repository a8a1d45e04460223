"""The diagnosis's stages from the effects on: probes and single fits, pairs, the verdict, and
the verdict's runs (:mod:`engine` runs them in order)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from . import stats
from .adequacy import adequate, needs_numerics
from .baseline import CHAIN
from .candidates import PAIRED, PROBES, Explanation, fit_pair, fit_single, rank_key
from .check import check, numerics, refine_points, relinearise
from .holdout_lengths import holdout_lengths
from .converge import converge, to_check
from .context import Baseline, FitContext
from .naming import lead_key
from .evaluate import Outcome, Task, all_ok, apply
from .result import num
from .stages import GapTest, outside
from .timing import lag_check


@dataclass(frozen=True)
class Candidates:
    """Stage 5: the single effects fitted on the linearised model (best first by p, J; the
    ones :func:`converge.to_check` picks checked by simulation and refined), their probe
    ``responses``, the
    Bonferroni count ``m`` and the baseline's own numerics candidate ``base_c``."""

    effects: list[Explanation]
    responses: dict
    m: int
    base_c: Explanation | None


def candidates_stage(ctx: FitContext, base: Baseline, gap: GapTest, chain_c: Explanation,
                     library: Sequence[str]) -> Candidates:
    """Stage 5: probe each library effect at the baseline, fit each on the linearised model,
    check the best and the chain's hypothesis by simulation (chord refinement; the
    candidate's own Jacobian and the model's numerics where it is significant yet refused)."""
    if not gap.left:
        return Candidates([], {}, 0, None)
    run, G, nf = ctx.run, ctx.G, ctx.nf
    if not library:
        run.stage("candidate checks")
        check([chain_c], ctx, base, m=1)
        return Candidates([], {}, 0, None)
    ptasks, index = [], []
    for name in library:
        kind, vals, _ = PROBES[name]
        for v in vals:
            vv = v if isinstance(v, tuple) else (v,)
            for d in ctx.fit_d:
                ptasks.append(Task(d, apply(ctx.params(d, base.u_s), ((name, vv),))))
            index.append((name, vv))
    run.stage("effect probes", len(ptasks))
    pouts = run(ptasks)
    responses: dict = {}
    for i, (name, vv) in enumerate(index):
        o = pouts[i * nf:(i + 1) * nf]
        responses.setdefault(name, []).append((vv, G.z(o) - base.z_raw if all_ok(o) else None))
    lin = base.linear(ctx)
    effects = []
    for name in library:
        c = fit_single(name, responses[name], lin)
        if c is not None:
            effects.append(c)
    m = len(effects) + math.comb(min(PAIRED, len(effects)), 2)
    for c in effects:
        c.p = stats.bonferroni_p(c.LR, c.k, m)
    effects.sort(key=lambda c: (c.p, c.J))
    chain_c.p = stats.bonferroni_p(chain_c.LR, chain_c.k, m + 1)
    run.stage("candidate checks")
    for c in effects:
        c.search.first_J = c.J
    checked = to_check(effects, base.J)
    check(checked + [chain_c], ctx, base, m=m, responses=responses)
    converge(checked, ctx, base, m, responses)
    base_c = Explanation((), {}, base.J, checked=True, baseline_u=np.r_[base.u_s, base.u_c])
    base_c.search.z_raw = base.z_raw
    base_c.search.zh_raw = ctx.H.z(base.outs[nf:]) if ctx.H else None
    has_h = bool(ctx.hold_d)
    need = [c for c in checked if needs_numerics(c, base.J_h, has_h, gap.replay)]
    again = [c for c in need if not c.search.converged]
    if again:
        # a strong effect changes how the knobs act: refit from its own Jacobian (knobs
        # held as written have none to refit); those :func:`converge` refined are done
        if ctx.sheet_lim > 0:
            relinearise(again, ctx)
        refine_points(again, ctx, base, m=m, responses=responses)
    if need:
        need = [c for c in need if needs_numerics(c, base.J_h, has_h, gap.replay)]
    if need:
        numerics(need + [base_c], ctx, base, responses)
    # the holdout's own rest lengths (each record's first seconds, refitted under the
    # candidate's cell: 17 short runs a record) for the candidates that can lead the verdict
    # and the lead's closest rival: the first by (checked, p, J), the first two by the
    # effective remainder (:func:`naming.lead_key`, the worse of fit and holdout records:
    # the naming rule judges a lead and its rivals so, :func:`naming.left`) and the first two
    # by the fit records alone; again while that order, with the holdouts refitted, puts
    # first a candidate whose holdout was judged on the baseline's lengths
    holdout_leads(effects, checked, ctx, base)
    return Candidates(effects, responses, m, base_c)


def holdout_leads(effects: list[Explanation], checked: list[Explanation], ctx: FitContext,
                  base: Baseline, rounds: int = 3) -> None:
    """:func:`~.holdout_lengths.holdout_lengths` for the checked candidates that can lead the
    verdict or be the lead's closest rival (:func:`candidates_stage`), until the first two by the
    effective remainder have their own holdout lengths (at most ``rounds`` times)."""
    if not effects:
        return
    done: set[int] = set()
    mine = {id(c) for c in checked}
    first = [sorted(effects, key=rank_key)[0]] + sorted(effects, key=lead_key(base.J))[:2]
    for _ in range(rounds):
        by_rem = sorted(effects, key=lead_key(base.J, base.J_h))
        todo = list({id(c): c for c in first + by_rem[:2]
                     if id(c) in mine and id(c) not in done}.values())
        if not todo:
            break
        holdout_lengths(todo, ctx)
        done |= {id(c) for c in todo}
        first = []


def pairs_stage(ctx: FitContext, base: Baseline, gap: GapTest,
                cands: Candidates) -> list[Explanation]:
    """Stage 6: the pairs among the ``PAIRED`` best single effects on the linearised model;
    the best checked by simulation and refined (its numerics where it needs them)."""
    lin = base.linear(ctx)
    pairs = []
    top = sorted(cands.effects, key=lambda c: (c.p, c.J))[:PAIRED]
    for i, a in enumerate(top):
        for b in top[i + 1:]:
            pc = fit_pair(a, b, cands.responses, lin)
            if pc is not None:
                pc.p = stats.bonferroni_p(pc.LR, pc.k, cands.m)
                pairs.append(pc)
    pairs.sort(key=lambda c: (c.p, c.J))
    if pairs:
        check(pairs[:1], ctx, base, m=cands.m, responses=cands.responses)
        holdout_lengths(pairs[:1], ctx)
        if needs_numerics(pairs[0], base.J_h, bool(ctx.hold_d), gap.replay):
            # the baseline again, refined the same way as the pair (pairs come from
            # effects, which come with the baseline's candidate)
            assert cands.base_c is not None
            numerics([pairs[0], cands.base_c], ctx, base, cands.responses)
    return pairs


@dataclass(frozen=True)
class VerdictStage:
    """Stage 7: what the diagnosis says and the explanation it rests on."""

    name: str                       # an effect (or pair), "none", "measurement chain", ...
    fit: Explanation | None         # the named effect or pair
    pairs: list[Explanation]
    chain_side: bool                # the gap is put on the measurement chain
    side: dict


def verdict_stage(ctx: FitContext, base: Baseline, gap: GapTest, chain_c: Explanation,
                  cands: Candidates, library: Sequence[str], rule=None) -> VerdictStage:
    """Stage 7: name the best single effect if it is significant and explains the gap and
    beats the chain's hypothesis; else the chain's hypothesis if it does; else the best pair;
    else ``unexplained`` (``none`` when no gap is left).  The chain's hypothesis with a
    load-cell lag beyond tolerance is refused when the profile lags too (:mod:`.timing`).

    "Explains the gap": with the numerics floor (``rule`` None) significant (likelihood
    ratio, p <= ALPHA) and adequate (within the null plus the numerics allowance,
    :func:`adequacy.adequate`), the lead the best by (p, J).  With a model-form floor,
    ``rule(explanation) -> bool`` (:func:`naming.judge`: with its prior, most of the
    baseline's excess on the fit and holdout records, and a remainder clearly below the best
    other explanation's) decides alone, the lead the checked effect of least effective
    remainder (:func:`naming.lead_key`: the worse of fit and holdout plus the prior's
    cost); what the named one
    leaves is reported against the floor (flagged when beyond it), never a reason to refuse
    a cause that explains most.  The likelihood ratio is reported there, not asked: it
    counts each observable's residuals as independent noise, while against a model-form
    floor they are mostly a systematic discrepancy (docs/diagnosis.md, "Naming against the
    floor")."""
    n_s, has_h, rp = ctx.n_s, bool(ctx.hold_d), gap.replay
    effects, base_c = cands.effects, cands.base_c
    pairs: list[Explanation] = []
    verdict_fit = None
    if not gap.left or not library:
        chain_c.p = stats.bonferroni_p(chain_c.LR, chain_c.k)
    out = outside(chain_c.fitted_u[n_s:])
    chain_c.adequate = chain_c.checked and adequate(chain_c, base.J_h, has_h, replay=rp)
    for c in effects:
        c.adequate = c.checked and adequate(c, base.J_h, has_h, base_c, rp)

    def explains(c: Explanation) -> bool:
        if not c.checked:
            return False
        if rule is None:
            return c.p <= stats.ALPHA and c.adequate
        return bool(rule(c))
    chain_ok = gap.left and explains(chain_c)
    timing = None
    if chain_ok and "load_cell.lag" in out:
        # a load cell lagging beyond tolerance delays the force only; a profile that lags
        # too puts the lag on the tool (or the camera's clock), which no knob holds
        timing = lag_check(ctx.fit_d, base.outs[:ctx.nf], chain_c.fitted_u[n_s:])
        chain_ok = not timing["tool_lags"]
    ranked = sorted(effects, key=rank_key if rule is None else lead_key(base.J, base.J_h))
    if gap.left and ranked:
        lead = ranked[0]
        if explains(lead) and not (chain_ok and chain_c.J < lead.J):
            verdict_fit = lead
        elif chain_ok:
            pass
        elif len(effects) >= 2:
            pairs = pairs_stage(ctx, base, gap, cands)
            if pairs:
                bp = pairs[0]
                bp.adequate = bp.checked and adequate(bp, base.J_h, has_h, base_c, rp)
                # a pair must beat each of its parts significantly
                if explains(bp):
                    verdict_fit = bp
    if (verdict_fit is not None and verdict_fit.J_parts and chain_ok
            and chain_c.J < verdict_fit.J):
        verdict_fit = None
    chain_side = chain_ok and verdict_fit is None
    name = ("none" if not gap.left else "+".join(verdict_fit.names) if verdict_fit
            else "measurement chain" if chain_side else "unexplained")
    side = {"side": ("measurement chain" if chain_side else "sheet" if gap.left
                     else "neither"),
            "chain_outside": out if chain_side else [],
            "chain_candidate": {"J": chain_c.J, "J_holdout": num(chain_c.J_holdout),
                                "p": num(chain_c.p), "adequate": chain_c.adequate,
                                "outside": out,
                                "values": {k.name: float(v * k.tolerance) for k, v in
                                           zip(CHAIN, chain_c.fitted_u[n_s:])}},
            "p_gap": gap.p, "timing": timing}
    return VerdictStage(name, verdict_fit, pairs, chain_side, side)


@dataclass(frozen=True)
class After:
    """Stage 8: the runs of what the verdict names (every record; the baseline's when it names
    nothing) and the chain values they are corrected by."""

    fit: Explanation | None         # the named effect, pair or the chain's hypothesis
    outs: list[Outcome]
    u_c: np.ndarray


def after_stage(ctx: FitContext, base: Baseline, verdict: VerdictStage,
                chain_c: Explanation) -> After:
    """Stage 8: the verdict's runs on the fit and holdout records, for the gap figures."""
    fit = verdict.fit or (chain_c if verdict.chain_side else None)
    if fit is None:
        return After(None, base.outs, base.u_c)
    u_v, n_s = fit.fitted_u, ctx.n_s
    cand = verdict.fit.candidate if verdict.fit else ()
    ctx.run.stage("verdict runs", len(ctx.data))
    outs = ctx.run([Task(d, apply(ctx.params(d, u_v[:n_s]), cand)) for d in ctx.data])
    return After(fit, outs, u_v[n_s:])
