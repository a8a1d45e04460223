"""Candidates checked by simulation: their runs, chord refinement and numerics (their
adequacy: :mod:`.adequacy`).

Numerics.  The diagnosis's model is a discretisation (N masses, its time steps); a
real cell is not.  What the model with the right effect leaves can therefore exceed
the effect-free null where the effect itself is strong (a large Kelvin creep, a stiff
bending): not a missing effect, the model's own discretisation error at that effect.
:func:`numerics` measures it the way a convergence study does: the candidate's run is
repeated on a refined discretisation (2 N + 1 masses, every step half as long,
:func:`refined`); J_num is the balanced misfit between the two runs.  For a method of
first order, the coarse run's error is about twice its change under one
halving; of order ``ORDER`` (a half, bounding what the convergence study shows) the
error is ``1 / (1 - 2^-ORDER)`` times the change, ``NUMERICS_FACTOR`` = 11.7 times its misfit
(J is quadratic).  The effect-free null already holds the baseline's own error; what a
candidate adds is the misfit of the difference between its change and the baseline's,
``J_num_added`` (not the difference of their misfits, which cancels where an effect moves
the discretisation error without growing it).  ``NUMERICS_FACTOR`` times that is the
allowance :func:`.adequacy.adequate` grants above the null's quantile, never more than
``GAP_SHARE`` of the baseline's excess.  The same change, projected
on the effect's response, is the shift the effect's value would take on the refined
model; ``ERROR_PER_CHANGE`` (3.4) times it widens the value's interval (:func:`numerics`).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..params.cell import CellParams

from ..sheet.effects import EFFECTS
from . import stats
from .candidates import PROBES, REFINE_STEPS, Explanation, magnitude, side_columns
from .context import Baseline, FitContext, Group, forward_jacobian, inward_steps
from .evaluate import Task, all_ok, apply

#: One refinement of the diagnosis's discretisation: factors on the solver's steps (the chain
#: goes from N to 2 N + 1 masses).
REFINEMENT = {"dt": 0.5, "dt_still": 0.5, "max_tool_step": 0.5, "dt_settle": 0.5}
#: The order of convergence assumed for the model's discretisation error (docs/model.md,
#: Convergence: F_max moves by 0.05 % and 0.04 % under two successive halvings of the pitch,
#: far from the asymptotic order 2; a half order bounds that behaviour).
ORDER = 0.5
#: Misfit of the coarse model's discretisation error, in units of its change under one
#: refinement: the error is 1 / (1 - 2^-ORDER) times that change, the misfit its square
#: (11.7 at half order; 4 at first order).
ERROR_PER_CHANGE = 1.0 / (1.0 - 2.0 ** -ORDER)
NUMERICS_FACTOR = ERROR_PER_CHANGE ** 2
#: Halvings toward the baseline of a candidate's first point whose runs fail (:func:`check`).
BACKTRACK = 3
#: The largest share of the baseline's excess misfit the allowance may cover (the model's
#: discretisation error is a small part of any effect it resolves: docs/model.md, Convergence).
GAP_SHARE = 0.25


def refined(p: CellParams, chain: bool = True) -> CellParams:
    """``p`` on the refined discretisation: 2 N + 1 masses (``chain``), every step half as
    long."""
    s = p.solver
    solver = replace(s, **{k: getattr(s, k) * f for k, f in REFINEMENT.items()})
    n = 2 * p.sheet.n_masses + 1 if chain else p.sheet.n_masses
    return replace(p, sheet=replace(p.sheet, n_masses=n), solver=solver)


def numerics(cands: list[Explanation], ctx: FitContext, base: Baseline, responses) -> None:
    """Each candidate's numerics misfit: its run against the same run refined
    (:func:`refined`).  ``J_num``: all of it (fit records); ``J_num_perp``: the part no
    refit of the baseline's knobs and the candidate's own values could absorb (the change
    projected off their columns ``A`` and the effects' responses; reported, not used);
    ``J_num_holdout``: all of it on the holdout records (no refit there);
    ``J_num_added`` (``_holdout``): the misfit of its change less the baseline's, where the
    baseline (the explanation without names) is among ``cands``.  A single effect's
    interval is widened by the value error the refinement implies."""
    cands = [c for c in cands
             if c.checked and c.search.z_raw is not None and math.isfinite(c.J)]
    if not cands:
        return
    run, G, H, n_s, A = ctx.run, ctx.G, ctx.H, ctx.n_s, base.solver.A
    tasks = []
    for c in cands:
        for d in ctx.data:
            tasks.append(Task(d, refined(apply(ctx.params(d, c.fitted_u[:n_s]),
                                               c.candidate))))
    outs = run(tasks)
    nd, nf = len(ctx.data), ctx.nf
    # where the finer chain does not run (its Newton gives up), the steps alone are refined,
    # for every candidate alike (the baseline's change is subtracted from theirs)
    if any(not all_ok(outs[i * nd:(i + 1) * nd]) for i in range(len(cands))):
        outs = run([Task(d, refined(apply(ctx.params(d, c.fitted_u[:n_s]), c.candidate),
                                    chain=False))
                    for c in cands for d in ctx.data])
        for c in cands:
            c.refinement = "steps"
    changes = {}
    for i, c in enumerate(cands):
        o = outs[i * nd:(i + 1) * nd]
        if not all_ok(o):
            continue                         # no allowance where no refined run runs
        dz = G.z(o[:nf]) - c.search.z_raw
        c.J_num = G.J(dz)
        dh = (H.z(o[nf:]) - c.search.zh_raw
              if H is not None and c.search.zh_raw is not None else None)
        changes[id(c)] = (dz, dh)
        E, slots = _columns(c, responses)
        M = np.hstack((A, E)) if E is not None else A
        Q = np.linalg.qr(M, mode="reduced")[0]
        perp = dz - Q @ (Q.T @ dz)
        c.J_num_perp = G.J(perp)
        if H is not None and dh is not None:
            c.J_num_holdout = H.J(dh)
        if E is not None and len(c.names) == 1:
            _widen(c, dz, A, E, slots)
    base_c = next((c for c in cands if not c.names and id(c) in changes), None)
    if base_c is not None:
        d0, h0 = changes[id(base_c)]
        for c in cands:
            if c.names and id(c) in changes:
                d, h = changes[id(c)]
                c.J_num_added = G.J(d - d0)
                if H is not None and h is not None and h0 is not None:
                    c.J_num_added_holdout = H.J(h - h0)


def effect_columns(name: str, responses, value) -> list[tuple[int, np.ndarray]] | None:
    """The linearised response of effect ``name`` at ``value``: (parameter index, column)
    pairs from its probes (a linear effect: one per parameter, the side ``value`` lies on,
    :func:`.candidates.side_columns`; a curve: the slope of the piecewise-linear response
    where ``value`` lies); None with fewer than two curve probes."""
    kind, _vals, _top = PROBES[name]
    resp = [(v, d) for v, d in responses[name] if d is not None]
    if kind == "linear":
        return side_columns(name, resp, value)
    mags = [(magnitude(name, v[0]), d) for v, d in resp]
    if len(mags) < 2:
        return None
    (m1, d1), (m2, d2) = mags
    a = magnitude(name, value[0])
    return [(0, d1 / m1 if a < m1 else (d2 - d1) / (m2 - m1))]


def _columns(c, responses):
    """(columns, parameter indices) of ``c``'s effects at its values (None for the
    baseline)."""
    out = []
    for name in c.names:
        out += effect_columns(name, responses, c.values[name]) or []
    if not out:
        return None, []
    return np.column_stack([col for _, col in out]), [k for k, _ in out]


def _widen(c, dz: np.ndarray, A: np.ndarray, E: np.ndarray, slots: list[int]) -> None:
    """Widen ``c``'s interval by the value error the refinement ``dz`` implies
    (``ERROR_PER_CHANGE`` times the shift)."""
    name = c.names[0]
    Q = np.linalg.qr(A, mode="reduced")[0]
    E_perp = E - Q @ (Q.T @ E)
    shift, *_ = np.linalg.lstsq(E_perp, dz - Q @ (Q.T @ dz), rcond=None)
    ivs = list(c.interval.get(name, [(v, v) for v in c.values[name]]))
    for k, s in zip(slots, shift):
        lo, hi = ivs[k]
        w = ERROR_PER_CHANGE * abs(float(s))
        b_lo, b_hi = EFFECTS[name].bounds[k]           # never beyond the effect's range
        ivs[k] = (max(lo - w, b_lo), min(hi + w, b_hi))
    c.interval[name] = ivs
    c.value_shift = {name: [float(s) for s in shift]}


def check(cands: list[Explanation], ctx: FitContext, base: Baseline, *, m: int,
          responses: dict | None = None) -> None:
    """Simulate the candidates at their fitted values (fit and holdout records); ``m``: the
    number of candidates their p-values are corrected for.

    With the probes' ``responses``, each effect candidate then takes up to ``REFINE_STEPS``
    chord steps (:func:`refine_points`).
    """
    points = []
    for c in cands:
        points.append((c, np.clip(base.u_s + c.fitted_u[:ctx.n_s], ctx.sheet_lo,
                                  ctx.sheet_hi), c.values))
    simulate_points(points, ctx, base, m=m, first=True)
    for _ in range(BACKTRACK):
        # a first point whose runs fail (a linearised fit far out: a tool offset at its
        # bounds pressing the sheet through the mould) is not the candidate's end: the point
        # halfway back to the baseline is run instead, so that its refinement starts
        points = [(c, base.u_s + 0.5 * (u - base.u_s), halfway(c.names, v))
                  for c, u, v in points if not math.isfinite(c.J)]
        if not points:
            break
        simulate_points(points, ctx, base, m=m, first=True)
    if responses is None:
        return
    refine_points(cands, ctx, base, m=m, responses=responses)


def halfway(names, values: dict) -> dict:
    """``values`` (effect name -> values) halfway back to no effect: each magnitude halved
    (power_law's 1 - n)."""
    out = dict(values)
    for name in names:
        kind = PROBES[name][0]
        v = values[name]
        if kind == "linear":
            out[name] = tuple(0.5 * float(x) for x in v)
        else:
            a = 0.5 * magnitude(name, float(v[0]))
            out[name] = ((1.0 - a) if name == "power_law" else a,) + tuple(v[1:])
    return out


def refine_points(cands: list[Explanation], ctx: FitContext, base: Baseline, *, m: int,
                  responses: dict, steps: int = REFINE_STEPS) -> None:
    """Up to ``steps`` chord steps of each effect candidate (its own Jacobian of the sheet
    knobs when :func:`relinearise` made one, else the baseline's), each simulated and kept
    only when it lowers J on the fit records.

    A step is kept on the fit records alone, so the steps run there alone; the holdout
    records run once, at each candidate's last kept point (:func:`_holdout_at_last`), with
    what the steps leave the same as when every step ran them too."""
    kept: dict = {}                       # id(candidate) -> its kept points, before each
    for _ in range(steps):
        points = []
        for c in cands:
            if c.chain_free or not math.isfinite(c.J) or c.search.z_raw is None:
                continue
            A_c = c.search.jacobian if c.search.jacobian is not None else base.A_sheet
            step = chord(c, A_c, ctx.G, responses, (ctx.sheet_lo, ctx.sheet_hi))
            if step is not None:
                points.append((c, *step))
        if not points:
            break
        simulate_points(points, ctx, base, m=m, first=False, kept=kept)
    _holdout_at_last(cands, ctx, kept)


def _snapshot(c: Explanation) -> tuple:
    """What a kept chord step changes in candidate ``c`` (to go back to it)."""
    s = c.search
    return (c.J, c.J_parts, c.values, c.LR, c.p, c.J_holdout, c.baseline_u,
            {n: list(iv) for n, iv in c.interval.items()}, s.z_raw, s.zh_raw, s.prev)


def _restore(c: Explanation, snap: tuple) -> None:
    s = c.search
    (c.J, c.J_parts, c.values, c.LR, c.p, c.J_holdout, c.baseline_u, c.interval, s.z_raw,
     s.zh_raw, s.prev) = snap


def _holdout_at_last(cands: list[Explanation], ctx: FitContext, kept: dict) -> None:
    """The holdout records' runs at the last kept point of each candidate whose chord steps
    ran on the fit records alone (:func:`refine_points`): its holdout residual and
    J_holdout.  Where a holdout record does not run there, the point is given back (a step
    whose runs fail is not kept) and the one before is taken, down to the point the steps
    began from (whose holdout runs ran)."""
    H, n_s = ctx.H, ctx.n_s
    todo = [c for c in cands if kept.get(id(c))]
    while todo and H is not None:
        tasks = []
        for c in todo:
            cand = tuple((n, c.values[n]) for n in c.names)
            tasks += [Task(d, apply(ctx.params(d, c.fitted_u[:n_s]), cand)) for d in ctx.hold_d]
        outs = ctx.run(tasks)
        nh, again = len(ctx.hold_d), []
        for i, c in enumerate(todo):
            o = outs[i * nh:(i + 1) * nh]
            if all_ok(o):
                c.search.zh_raw = H.z(o)
                c.J_holdout = H.J_with_chain(c.search.zh_raw, c.fitted_u[n_s:])
                continue
            _restore(c, kept[id(c)].pop())
            if kept[id(c)]:
                again.append(c)
        todo = again


def relinearise(cands: list[Explanation], ctx: FitContext) -> None:
    """Each candidate's own Jacobian of the sheet knobs, at its point with its effect on
    (forward differences of half a tolerance, toward the inside of the +-1 box): the
    baseline's Jacobian is taken without any effect, and a strong effect (a large creep, a
    friction) changes how the knobs act, so chord steps from it stall short of the fit."""
    for c in cands:
        u = np.asarray(c.fitted_u[:ctx.n_s], float)

        def at(j: int, h: float, c=c, u=u) -> list:
            uj = u.copy()
            uj[j] += h
            return [apply(ctx.params(d, uj), c.candidate) for d in ctx.fit_d]

        def invalid(j: int, c=c, u=u) -> list:
            return [apply(ctx.params(d, u), c.candidate) for d in ctx.fit_d]
        c.search.jacobian = forward_jacobian(ctx, c.search.simulated_z, at,
                                             inward_steps(u, np.ones(ctx.n_s), 0.5), invalid)
        c.search.prev, c.search.damp = None, 1.0


def simulate_points(points, ctx: FitContext, base: Baseline, *, m: int, first: bool,
                    kept: dict | None = None) -> None:
    """Run each (candidate, sheet u, values) point on the fit and holdout records and take
    it as the candidate's evidence (the first time always; later only when J drops, else
    the candidate's step is halved).  With ``kept`` (a later point only), the fit records
    alone: each point taken is noted in ``kept[id(candidate)]`` (what the candidate was
    before it) and its holdout runs are left to :func:`_holdout_at_last`."""
    G, H, nf = ctx.G, ctx.H, ctx.nf
    data = ctx.fit_d if kept is not None and not first else ctx.data
    tasks = []
    for c, u_sheet, vals in points:
        cand = tuple((n, vals[n]) for n in c.names)
        for d in data:
            tasks.append(Task(d, apply(ctx.params(d, u_sheet), cand)))
    outs = ctx.run(tasks)
    nd = len(data)
    for i, (c, u_sheet, vals) in enumerate(points):
        o = outs[i * nd:(i + 1) * nd]
        if not all_ok(o):
            if first:
                c.checked, c.J, c.p = True, math.inf, 1.0
            else:
                c.search.damp *= 0.5         # a step whose runs fail lowers nothing either
            continue
        z_raw = G.z(o[:nf])
        if c.chain_free:
            uc, J, zc = base.chain_fit(z_raw, ctx.chain_free)
        else:
            uc, J, zc = base.chain_fit(z_raw, ctx.chain_lim)
        s = c.search
        if not first and not J < c.J:
            s.damp *= 0.5
            continue
        if kept is not None and not first:
            kept.setdefault(id(c), []).append(_snapshot(c))
        if not first:
            s.prev = (s.z_raw, c.baseline_u[:len(u_sheet)].copy(), dict(c.values))
        for n in c.names:
            if n in c.interval:
                c.interval[n] = [(lo + vals[n][k] - c.values[n][k],
                                  hi + vals[n][k] - c.values[n][k])
                                 for k, (lo, hi) in enumerate(c.interval[n])]
        c.J, c.J_parts, s.z_raw, c.values = J, G.stack.J_parts(zc), z_raw, dict(vals)
        c.LR = stats.likelihood_ratio(base.parts, c.J_parts, base.n_eff)
        c.p = stats.bonferroni_p(c.LR, c.k, m)
        if H is not None and len(o) > nf:
            s.zh_raw = H.z(o[nf:])
            c.J_holdout = H.J_with_chain(s.zh_raw, uc)
        c.baseline_u = np.r_[u_sheet, uc]
        c.checked = True


def chord(c: Explanation, A_sheet: np.ndarray, G: Group, responses: dict,
          box: tuple | None = None):
    """The next point (sheet u, values) of candidate ``c``: one linearised step from its run
    (the sheet knobs' Jacobian ``A_sheet`` within ``box`` (lower, upper) [tolerances],
    default |u| <= 1, the effects' probe responses; a curve effect of a single candidate by
    the secant through its last two simulated points); None when an effect has too few."""
    n_s = A_sheet.shape[1]
    s = c.search
    cols, lo_e, hi_e, slots = [], [], [], []
    for name in c.names:
        kind, vals, top = PROBES[name]
        e = EFFECTS[name]
        cur = c.values[name]
        columns = effect_columns(name, responses, cur)
        if columns is None:
            return None
        if kind == "linear":
            for k, col in columns:
                cols.append(col)
                lo_e.append(e.bounds[k][0] - cur[k])
                hi_e.append(e.bounds[k][1] - cur[k])
                slots.append((name, k, False))
        else:
            a = magnitude(name, cur[0])
            col = columns[0][1]
            if s.prev is not None and len(c.names) == 1:
                # secant: the response between the last two simulated points, the baseline's
                # linear part removed
                z_p, u_p, v_p = s.prev
                da = a - magnitude(name, v_p[name][0])
                if abs(da) > 1e-12:
                    col = (s.simulated_z - z_p - A_sheet @ (c.fitted_u[:n_s] - u_p)) / da
            cols.append(col)
            lo_e.append(-a)
            hi_e.append(magnitude(name, top) - a)
            slots.append((name, 0, True))
    u_cur = c.fitted_u[:n_s]
    solver = G.solver(A_sheet)
    lim = np.ones(G.chain.shape[1])
    lo_s, hi_s = (-np.ones(n_s), np.ones(n_s)) if box is None else box
    du, _ = solver.solve(s.simulated_z, np.r_[lo_s - u_cur, -lim], np.r_[hi_s - u_cur, lim],
                         np.column_stack(cols), (np.array(lo_e), np.array(hi_e)))
    du = du * s.damp
    u_new = np.clip(u_cur + du[:n_s], lo_s, hi_s)
    vals = {n: list(v) for n, v in c.values.items()}
    for (name, k, is_curve), x in zip(slots, du[solver.A.shape[1]:]):
        if is_curve:
            a = magnitude(name, vals[name][0]) + x
            vals[name][0] = (1.0 - a) if name == "power_law" else a
        else:
            vals[name][k] = vals[name][k] + x
    return u_new, {n: tuple(float(x) for x in v) for n, v in vals.items()}
