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
   effect-free distribution (p_gap).  p_gap > ALPHA: ``none``.
5. Which effect.  Each library effect is probed at the baseline by two
   simulations per fit record (one per axis for tool_offset, one for
   mass_error, both linear) and fitted jointly with the baseline's knobs on
   the linearised model (piecewise linear in the effect's magnitude); the two
   best (by their likelihood-ratio p-value) are checked by simulation on the
   fit and holdout records.  Named: p (Bonferroni over the candidates) <=
   ALPHA, and what it leaves is adequate (excess within the effect-free null's
   95 % quantile on fit and holdout records, and the holdout improves).  Else
   the pairs among the three best (linearised, the best checked by
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
from dataclasses import dataclass, field, replace
from typing import Callable, Sequence

import numpy as np

from ..sheet.effects import EFFECT_NAMES, EFFECTS
from ..params.params import CellParams
from ..records.record import Record
from ..params.schema import ParameterError
from . import stats
from .baseline import CHAIN, SHEET, values as knob_values, with_sheet
from .compare import RecordData, noise_level, residuals
from .evaluate import Candidate, Outcome, Runner, Task, apply
from .linear import Solver, Stack

#: Probe values per effect: (kind, values).  "curve": a scalar effect probed at two magnitudes,
#: the response piecewise linear through 0 and both; "linear": one column per probe (signed).
PROBES: dict = {
    "friction_mould": ("curve", (0.2, 0.5), 0.8),
    "friction_tool": ("curve", (0.2, 0.5), 0.8),
    "bending": ("curve", (3e-6, 1e-5), 1.6e-5),
    "kelvin_c1": ("curve", (500.0, 2000.0), 3000.0),
    "power_law": ("curve", (0.8, 0.55), 0.35),
    "thinning": ("curve", (0.6, 1.6), 2.5),
    "tool_offset": ("linear", ((1e-3, 0.0), (0.0, 1e-3)), None),
    "mass_error": ("linear", ((0.25,),), None),
}
GRID = 41          # magnitudes tried per curve effect on the linearised model
CHECKED = 2        # single effects checked by simulation
PAIRED = 3         # pairs among this many best single effects
REFINE_STEPS = 8   # chord (secant) steps of each checked candidate (each simulated)


@dataclass
class Candidate_:
    """One candidate explanation (an effect or a pair) and its evidence."""

    names: tuple[str, ...]
    values: dict                    # name -> tuple of values
    J: float                        # fit records, balanced misfit (simulated once checked)
    J_parts: dict = field(default_factory=dict)
    J_holdout: float = math.nan
    LR: float = math.nan
    p: float = math.nan             # Bonferroni-corrected
    k: int = 1
    checked: bool = False
    adequate: bool = False
    baseline_u: np.ndarray | None = None
    interval: dict = field(default_factory=dict)
    chain_free: bool = False        # the measurement chain's hypothesis (chain beyond tolerance)
    z_raw: np.ndarray | None = field(default=None, repr=False)   # fit records' z at the last run
    prev: tuple | None = field(default=None, repr=False)         # (z_raw, u_sheet, values) before
    damp: float = 1.0                                            # step factor (halved on a miss)

    @property
    def candidate(self) -> Candidate:
        return tuple((n, self.values[n]) for n in self.names)

    @property
    def n_params(self) -> int:
        return self.k


@dataclass
class Diagnosis:
    """Everything the report and the JSON say."""

    verdict: str
    verdict_fit: Candidate_ | None
    effects: list[Candidate_]
    pairs: list[Candidate_]
    where: list[dict]
    gap_before: dict
    gap_after: dict
    gap_baseline: dict
    noise: dict
    J0: float
    J0_holdout: float
    J_base: float
    J_base_holdout: float
    baseline: dict                  # knob -> {value, written, u, tolerance, unit, outside}
    side: dict                      # {"side": ..., "p_chain": ..., "chain_outside": [...]}
    p_gap: float
    n_eff: dict
    records: list[str]
    holdout: list[str]
    runs: int
    signature: dict | None = None
    corrected: CellParams | None = None
    residual_maps: list = field(default_factory=list)

    def explained(self, fr: Candidate_, holdout: bool = False) -> float:
        """Fraction of the baseline's excess misfit the candidate removes."""
        Jb = self.J_base_holdout if holdout else self.J_base
        J = fr.J_holdout if holdout else fr.J
        if not (math.isfinite(Jb) and math.isfinite(J)) or Jb - 1.0 <= 0:
            return math.nan
        return (Jb - J) / (Jb - 1.0)

    @property
    def baseline_took(self) -> float:
        """Fraction of the nominal model's excess misfit the calibrated baseline removes."""
        return (self.J0 - self.J_base) / (self.J0 - 1.0) if self.J0 > 1.0 else math.nan

    def to_json(self) -> dict:
        def eff(fr: Candidate_, rank: int) -> dict:
            return {"name": "+".join(fr.names), "rank": rank, "checked": fr.checked,
                    "params": {n: list(v) for n, v in fr.values.items()},
                    "interval": {n: [list(iv) for iv in ivs] for n, ivs in fr.interval.items()},
                    "J_fit": fr.J, "J_holdout": _num(fr.J_holdout), "LR": _num(fr.LR),
                    "p": _num(fr.p), "adequate": fr.adequate,
                    "explained_fit": _num(self.explained(fr)),
                    "explained_holdout": _num(self.explained(fr, True))}
        ranked = sorted(self.effects + self.pairs, key=_rank_key)
        vf = self.verdict_fit
        return {"verdict": self.verdict,
                "verdict_params": {n: list(v) for n, v in vf.values.items()} if vf else None,
                "verdict_interval": ({n: [list(iv) for iv in ivs]
                                      for n, ivs in vf.interval.items()}
                                     if vf else None),
                "verdict_p": _num(vf.p) if vf else None,
                "p_gap": self.p_gap, "side": self.side, "baseline": self.baseline,
                "baseline_took": _num(self.baseline_took),
                "J_nominal": {"fit": self.J0, "holdout": _num(self.J0_holdout)},
                "J_baseline": {"fit": self.J_base, "holdout": _num(self.J_base_holdout)},
                "n_eff": self.n_eff, "effects": [eff(f, i + 1) for i, f in enumerate(ranked)],
                "signature": self.signature, "where": self.where,
                "gap_before": self.gap_before, "gap_baseline": self.gap_baseline,
                "gap_after": self.gap_after, "noise": self.noise, "records": self.records,
                "holdout": self.holdout, "simulations": self.runs}


def _num(v):
    return None if v is None or not math.isfinite(v) else float(v)


def _rank_key(f: Candidate_):
    return (not f.checked, f.p if math.isfinite(f.p) else 1.0, f.J)


class _Group:
    """The records of one group (fit or holdout) and their stacked residuals."""

    def __init__(self, data: list[RecordData], sp: float, sf: float, nominal: list[Outcome]):
        self.data = data
        self.stack = Stack([d.point_frame for d in data], [d.record.has_wrench for d in data],
                           sp, sf)
        self.stack.set_force_count(nominal)
        self.chain = self.stack.chain_columns(nominal) if data else np.zeros((0, len(CHAIN)))

    def z(self, outs: list[Outcome]) -> np.ndarray:
        return self.stack.vec(outs)

    def J(self, z: np.ndarray) -> float:
        return float(z @ z)


def _ok(outs: list[Outcome]) -> bool:
    return all(o.ok for o in outs)


def diagnose(records: Sequence[Record], holdout: Sequence[Record] = (),
             library: Sequence[str] = EFFECT_NAMES, jobs: int | None = None,
             progress: Callable[[int], None] | None = None,
             executor: Executor | None = None) -> Diagnosis:
    """Diagnose the gap between ``records`` (fitted) and their scenario; check on ``holdout``."""
    from . import gap, where as where_mod
    from .signature import describe
    if not records:
        raise ValueError("diagnose needs at least one record to fit")
    library = tuple(library)
    data = [RecordData.of(r) for r in list(records) + list(holdout)]
    nf = len(records)
    fit_d, hold_d = data[:nf], data[nf:]
    with Runner(executor, jobs, progress) as run:
        # 1. nominal: noise
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
        outs = run(tasks)
        cols = []
        for j in range(len(SHEET)):
            o = outs[j * nf:(j + 1) * nf]
            cols.append((G.z(o) - z0) / steps[j] if _ok(o) else np.zeros_like(z0))
        A_sheet = np.column_stack(cols)
        A = np.hstack((A_sheet, G.chain))
        solver = Solver(A)
        n_s = len(SHEET)
        chain_lim = np.ones(len(CHAIN))                      # the baseline: within tolerance
        chain_free = np.array([k.limit for k in CHAIN])      # the chain hypothesis: beyond it
        lo = np.r_[-np.ones(n_s), -chain_lim]
        hi = np.r_[np.ones(n_s), chain_lim]

        def base_params(d: RecordData, u_s: np.ndarray) -> CellParams:
            return with_sheet(d.record.scenario, {k.name: float(v) for k, v in zip(SHEET, u_s)})

        def chain_fit(z: np.ndarray, chain_lo=-chain_lim, chain_hi=chain_lim):
            """Chain values for residual ``z`` (sheet held): (u_chain, J, corrected z)."""
            s = Solver(G.chain)
            u, J = s.solve(z, chain_lo, chain_hi)
            return u, J, z + G.chain @ u

        u_lin, _ = solver.solve(z0, lo, hi)
        best = None
        u_s = np.zeros(n_s)
        tried = [(np.zeros(n_s), nominal)]
        for _it in range(2):
            u_try = np.clip(u_lin[:n_s], -1, 1)
            try:
                outs = run([Task(d, base_params(d, u_try), keep_run=True) for d in data])
            except ParameterError:
                break
            tried.append((u_try, outs))
            if not _ok(outs[:nf]):
                break
            zb = G.z(outs[:nf])
            # chord step: same Jacobian from the new point
            du, _ = solver.solve(zb, np.r_[-1 - u_try, -chain_lim], np.r_[1 - u_try, chain_lim])
            u_lin = np.r_[u_try + du[:n_s], du[n_s:]]
        for u_try, outs in tried:
            if not _ok(outs[:nf]) or (H and not _ok(outs[nf:])):
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

        # 3. gap test
        p_gap = stats.gap_p_value(J_base - 1.0)
        gap_left = p_gap <= stats.ALPHA

        # 4. which side: the chain beyond its tolerance (no simulation: linear), checked
        u_ch, J_ch = solver.solve(zB_raw, np.r_[-1 - u_s, -chain_free], np.r_[1 - u_s, chain_free])
        chain_c = Candidate_((), {}, J_ch, G.stack.J_parts(solver.residual(zB_raw, u_ch)),
                             baseline_u=u_ch, chain_free=True)
        outside = [k.name for k, v in zip(CHAIN, u_ch[n_s:]) if abs(v) > 1.0 + 1e-6]
        chain_c.k = max(len(outside), 1)
        chain_c.LR = stats.likelihood_ratio(parts_B, chain_c.J_parts, n_eff)

        # 5. effects: probes at the baseline, linearised fits
        effects: list[Candidate_] = []
        pairs: list[Candidate_] = []
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
            pouts = run(ptasks)
            for i, (name, vv) in enumerate(index):
                o = pouts[i * nf:(i + 1) * nf]
                responses.setdefault(name, []).append(
                    (vv, G.z(o) - zB_raw if _ok(o) else None))
            base_solver = Solver(A)
            blo = np.r_[-1 - u_s, -chain_lim]
            bhi = np.r_[1 - u_s, chain_lim]
            for name in library:
                c = _fit_linear(name, responses[name], zB_raw, base_solver, blo, bhi, G, n_eff,
                                parts_B)
                if c is not None:
                    effects.append(c)
            m = len(effects) + math.comb(min(PAIRED, len(effects)), 2)
            for c in effects:
                c.p = min(1.0, stats.chi2_sf(c.LR, c.k) * m)
            effects.sort(key=lambda c: (c.p, c.J))
            chain_c.p = min(1.0, stats.chi2_sf(chain_c.LR, chain_c.k) * (m + 1))
            _check(effects[:CHECKED] + [chain_c], run, fit_d, hold_d, G, H, u_s, n_s, base_params,
                   chain_fit,
                   parts_B, n_eff, J_base_h, m, chain_free, (A_sheet, responses, REFINE_STEPS))
        elif gap_left:
            _check([chain_c], run, fit_d, hold_d, G, H, u_s, n_s, base_params, chain_fit,
                   parts_B, n_eff, J_base_h, 1, chain_free)
        # decision
        verdict_fit = None
        if not gap_left or not library:
            chain_c.p = min(1.0, stats.chi2_sf(chain_c.LR, chain_c.k))
        outside = [k.name for k, v in zip(CHAIN, chain_c.baseline_u[n_s:]) if abs(v) > 1.0 + 1e-6]
        chain_c.adequate = chain_c.checked and _adequate(chain_c, J_base_h, bool(hold_d))
        chain_ok = gap_left and chain_c.checked and chain_c.p <= stats.ALPHA and chain_c.adequate
        for c in effects:
            c.adequate = c.checked and _adequate(c, J_base_h, bool(hold_d))
        ranked = sorted(effects, key=_rank_key)
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
                        pc = _fit_pair(a, b, responses, zB_raw, Solver(A),
                                       np.r_[-1 - u_s, -chain_lim],
                                       np.r_[1 - u_s, chain_lim], G, n_eff, parts_B)
                        if pc is not None:
                            pc.p = min(1.0, stats.chi2_sf(pc.LR, pc.k) * m)
                            pairs.append(pc)
                pairs.sort(key=lambda c: (c.p, c.J))
                if pairs:
                    _check(pairs[:1], run, fit_d, hold_d, G, H, u_s, n_s, base_params, chain_fit,
                           parts_B, n_eff, J_base_h, m, chain_free,
                           (A_sheet, responses, REFINE_STEPS))
                    bp = pairs[0]
                    bp.adequate = bp.checked and _adequate(bp, J_base_h, bool(hold_d))
                    # a pair must beat each of its parts significantly
                    if bp.checked and bp.p <= stats.ALPHA and bp.adequate:
                        verdict_fit = bp
        if (verdict_fit is not None and verdict_fit.J_parts and chain_ok
                and chain_c.J < verdict_fit.J):
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
            after = run([Task(d, apply(base_params(d, u_v[:n_s]), cand)) for d in data])
            u_cv = u_v[n_s:]
        else:
            after, u_cv = base_outs, u_c
        runs = run.runs

    vfc = verdict_fit or verdict_fit_chain
    corrected = (apply(base_params(fit_d[0], vfc.baseline_u[:n_s]), vfc.candidate)
                 if vfc else base_params(fit_d[0], u_s))
    baseline_tab = _baseline_table(fit_d[0].record.scenario,
                                   vfc.baseline_u if vfc else np.r_[u_s, u_c])
    nom_res = [residuals(d, o.run) for d, o in zip(data, nominal)]
    base_runs = [o.run for o in base_outs]
    base_res = [_chain_correct(residuals(d, o.run), o, u_c) for d, o in zip(data, base_outs)]
    after_res = ([_chain_correct(_as_res(d, o, base_runs[i]), o, u_cv) for i, (d, o) in
                  enumerate(zip(data, after))] if vfc else base_res)
    fit_idx, hold_idx = tuple(range(nf)), tuple(range(nf, len(data)))
    diag = Diagnosis(verdict, verdict_fit, effects, pairs, [], {}, {}, {},
                     {"profile_m": sp, "force_N": sf}, J0, J0h, J_base, J_base_h, baseline_tab,
                     side, p_gap, n_eff, [d.record.name for d in fit_d],
                     [d.record.name for d in hold_d], runs, corrected=corrected)
    diag.where = where_mod.rank(fit_d, base_res[:nf], base_runs[:nf], sp, sf)
    diag.gap_before = gap.figures(data, nom_res, fit_idx, hold_idx, sp, sf)
    before = diag.gap_before
    diag.gap_baseline = gap.figures(data, base_res, fit_idx, hold_idx, sp, sf, before=before)
    diag.gap_after = gap.figures(data, after_res, fit_idx, hold_idx, sp, sf, before=before)
    if verdict not in ("none", "measurement chain"):
        diag.signature = describe(fit_d, base_res[:nf], base_runs[:nf], sp, sf, u_c)
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


def _curve(resp, a: float) -> np.ndarray:
    """Piecewise-linear response at magnitude ``a`` through (0, 0) and the probes."""
    (m1, d1), (m2, d2) = resp
    if a <= m1:
        return d1 * (a / m1)
    return d1 + (d2 - d1) * ((a - m1) / (m2 - m1))


def _magnitude(name: str, v: float) -> float:
    return 1.0 - v if name == "power_law" else v


def _fit_linear(name, resp, zB_raw, solver: Solver, lo, hi, G: _Group, n_eff, parts_B):
    kind, vals, top = PROBES[name]
    e = EFFECTS[name]
    if any(d is None for _, d in resp):
        resp = [(v, d) for v, d in resp if d is not None]
        if not resp:
            return None
    if kind == "linear":
        cols = []
        for v, d in resp:
            k = int(np.argmax(np.abs(v)))
            cols.append((k, d / v[k]))
        E = np.column_stack([c for _, c in cols])
        elo = np.array([e.bounds[k][0] for k, _ in cols])
        ehi = np.array([e.bounds[k][1] for k, _ in cols])
        u, J = solver.solve(zB_raw, lo, hi, E, (elo, ehi))
        vals_fit = [0.0] * e.n_params
        for (k, _), x in zip(cols, u[solver.A.shape[1]:]):
            vals_fit[k] = float(x)
        z = solver.residual(zB_raw, u, E)
        c = Candidate_((name,), {name: tuple(vals_fit)}, J, G.stack.J_parts(z), k=len(cols),
                       baseline_u=u[:solver.A.shape[1]])
        # 95 % interval: the value whose LR drop is 3.84 (effective sample size), the baseline
        # refitted (the column with the baseline's columns projected out)
        e_perp = E - solver.Q @ (solver.Q.T @ E)
        ntot = sum(n_eff.values())
        ivs = [(v, v) for v in vals_fit]
        for (k, _), col in zip(cols, e_perp.T):
            h = float(col @ col)
            half = math.sqrt(3.84 * J / (ntot * h)) if h > 0 else math.inf
            ivs[k] = (vals_fit[k] - half, vals_fit[k] + half)
        c.interval = {name: ivs}
    else:
        mags = [(_magnitude(name, v[0]), d) for v, d in resp]
        if len(mags) < 2:
            mags = [mags[0], (2 * mags[0][0], 2 * mags[0][1])]
        grid = np.linspace(0.0, _magnitude(name, top), GRID)
        Js, us = [], []
        for a in grid:
            u, J = solver.solve(zB_raw + _curve(mags, a), lo, hi)
            Js.append(J)
            us.append(u)
        i = int(np.argmin(Js))
        a = float(grid[i])
        # 95 % interval: magnitudes within the LR drop of 3.84 (effective sample size)
        ntot = sum(n_eff.values())
        ok = [g for g, J in zip(grid, Js) if ntot * math.log(J / Js[i]) <= 3.84]
        z = zB_raw + _curve(mags, a) + solver.A @ us[i]
        v = 1.0 - a if name == "power_law" else a
        lo_a, hi_a = min(ok), max(ok)
        iv = sorted((1.0 - lo_a, 1.0 - hi_a)) if name == "power_law" else [lo_a, hi_a]
        c = Candidate_((name,), {name: (v,)}, Js[i], G.stack.J_parts(z), k=1, baseline_u=us[i])
        c.interval = {name: [tuple(iv)]}
    c.LR = stats.likelihood_ratio(parts_B, c.J_parts, n_eff)
    return c


def _fit_pair(a: Candidate_, b: Candidate_, responses, zB_raw, solver: Solver, lo, hi, G, n_eff,
              parts_B):
    """Two effects together on the linearised model (responses add)."""
    na, nb = a.names[0], b.names[0]
    best = None
    grids = []
    for n in (na, nb):
        kind, vals, top = PROBES[n]
        resp = [(v, d) for v, d in responses[n] if d is not None]
        if kind == "linear":
            grids.append((n, "linear", resp))
        else:
            mags = [(_magnitude(n, v[0]), d) for v, d in resp]
            grids.append((n, "curve", (mags, np.linspace(0, _magnitude(n, top), 17))))
    curve = [g for g in grids if g[1] == "curve"]
    lin = [g for g in grids if g[1] == "linear"]
    E, elo, ehi, kidx = None, [], [], []
    if lin:
        cols = []
        for n, _, resp in lin:
            e = EFFECTS[n]
            for v, d in resp:
                k = int(np.argmax(np.abs(v)))
                cols.append(d / v[k])
                elo.append(e.bounds[k][0])
                ehi.append(e.bounds[k][1])
                kidx.append((n, k))
        E = np.column_stack(cols)
    import itertools
    axes = [g[2][1] for g in curve] or [[None]]
    for combo in itertools.product(*axes):
        shift = np.zeros_like(zB_raw)
        for (n, _, (mags, _g)), x in zip(curve, combo):
            if x is not None:
                shift = shift + _curve(mags, x)
        u, J = solver.solve(zB_raw + shift, lo, hi, E,
                            (np.array(elo), np.array(ehi)) if E is not None else None)
        if best is None or J < best[0]:
            best = (J, u, combo, shift)
    J, u, combo, shift = best
    values = {}
    for (n, _, _), x in zip(curve, combo):
        values[n] = ((1.0 - x) if n == "power_law" else float(x),)
    if E is not None:
        for n in {n for n, _ in kidx}:
            vv = [0.0] * EFFECTS[n].n_params
            for (nn, k), x in zip(kidx, u[solver.A.shape[1]:]):
                if nn == n:
                    vv[k] = float(x)
            values[n] = tuple(vv)
    k0 = solver.A.shape[1]
    z = zB_raw + shift + solver.A @ u[:k0] + (E @ u[k0:] if E is not None else 0.0)
    names = tuple(sorted((na, nb)))
    c = Candidate_(names, {n: values[n] for n in names}, J, G.stack.J_parts(z),
                   k=a.k + b.k, baseline_u=u[:solver.A.shape[1]])
    c.interval = {n: [(v, v) for v in values[n]] for n in names}
    c.LR = stats.likelihood_ratio(parts_B, c.J_parts, n_eff)
    return c


def _check(cands, run, fit_d, hold_d, G, H, u_s, n_s, base_params, chain_fit, parts_B, n_eff,
           J_base_h, m, chain_free=None, refine=None) -> None:
    """Simulate the candidates at their fitted values (fit and holdout records).

    With ``refine = (A_sheet, responses, steps)``, each effect candidate then takes up to
    ``steps`` chord steps (the baseline's Jacobian and the effect's probe response, from the
    simulated point), each simulated and kept only when it lowers J on the fit records.
    """
    points = []
    for c in cands:
        points.append((c, np.clip(u_s + c.baseline_u[:n_s], -1, 1), c.values))
    _simulate_points(points, run, fit_d, hold_d, G, H, base_params, chain_fit, parts_B, n_eff, m,
                     chain_free, first=True)
    if refine is None:
        return
    A_sheet, responses, steps = refine
    for _ in range(steps):
        points = []
        for c in cands:
            if c.chain_free or not math.isfinite(c.J) or c.z_raw is None:
                continue
            step = _chord(c, A_sheet, G, responses, n_s)
            if step is not None:
                points.append((c, *step))
        if not points:
            break
        _simulate_points(points, run, fit_d, hold_d, G, H, base_params, chain_fit, parts_B, n_eff,
                         m, chain_free, first=False)


def _simulate_points(points, run, fit_d, hold_d, G, H, base_params, chain_fit, parts_B, n_eff, m,
                     chain_free, first: bool) -> None:
    tasks = []
    for c, u_sheet, vals in points:
        cand = tuple((n, vals[n]) for n in c.names)
        for d in list(fit_d) + list(hold_d):
            tasks.append(Task(d, apply(base_params(d, u_sheet), cand)))
    outs = run(tasks)
    nd = len(fit_d) + len(hold_d)
    for i, (c, u_sheet, vals) in enumerate(points):
        o = outs[i * nd:(i + 1) * nd]
        if not _ok(o):
            if first:
                c.checked, c.J, c.p = True, math.inf, 1.0
            continue
        z_raw = G.z(o[:len(fit_d)])
        if c.chain_free:
            uc, J, zc = chain_fit(z_raw, -chain_free, chain_free)
        else:
            uc, J, zc = chain_fit(z_raw)
        if not first and not J < c.J:
            c.damp *= 0.5
            continue
        if not first:
            c.prev = (c.z_raw, c.baseline_u[:len(u_sheet)].copy(), dict(c.values))
        for n in c.names:
            if n in c.interval:
                c.interval[n] = [(lo + vals[n][k] - c.values[n][k],
                                  hi + vals[n][k] - c.values[n][k])
                                 for k, (lo, hi) in enumerate(c.interval[n])]
        c.J, c.J_parts, c.z_raw, c.values = J, G.stack.J_parts(zc), z_raw, dict(vals)
        c.LR = stats.likelihood_ratio(parts_B, c.J_parts, n_eff)
        c.p = min(1.0, stats.chi2_sf(c.LR, c.k) * m)
        if H is not None:
            c.J_holdout = H.J(H.z(o[len(fit_d):]) + H.chain @ uc)
        c.baseline_u = np.r_[u_sheet, uc]
        c.checked = True


def _chord(c, A_sheet, G, responses, n_s):
    """The next point (sheet u, values) of candidate ``c``: one linearised step from its run."""
    cols, lo_e, hi_e, slots = [], [], [], []
    for name in c.names:
        kind, vals, top = PROBES[name]
        resp = [(v, d) for v, d in responses[name] if d is not None]
        e = EFFECTS[name]
        cur = c.values[name]
        if kind == "linear":
            for v, d in resp:
                k = int(np.argmax(np.abs(v)))
                cols.append(d / v[k])
                lo_e.append(e.bounds[k][0] - cur[k])
                hi_e.append(e.bounds[k][1] - cur[k])
                slots.append((name, k, False))
        else:
            mags = [(_magnitude(name, v[0]), d) for v, d in resp]
            if len(mags) < 2:
                return None
            (m1, d1), (m2, d2) = mags
            a = _magnitude(name, cur[0])
            col = d1 / m1 if a < m1 else (d2 - d1) / (m2 - m1)
            if c.prev is not None and len(c.names) == 1:
                # secant: the response between the last two simulated points, the baseline's
                # linear part removed
                z_p, u_p, v_p = c.prev
                da = a - _magnitude(name, v_p[name][0])
                if abs(da) > 1e-12:
                    col = (c.z_raw - z_p - A_sheet @ (c.baseline_u[:n_s] - u_p)) / da
            cols.append(col)
            lo_e.append(-a)
            hi_e.append(_magnitude(name, top) - a)
            slots.append((name, 0, True))
    u_cur = c.baseline_u[:n_s]
    A = np.hstack((A_sheet, G.chain))
    lim = np.ones(G.chain.shape[1])
    du, _ = Solver(A).solve(c.z_raw, np.r_[-1 - u_cur, -lim], np.r_[1 - u_cur, lim],
                            np.column_stack(cols), (np.array(lo_e), np.array(hi_e)))
    du = du * c.damp
    u_new = np.clip(u_cur + du[:n_s], -1, 1)
    vals = {n: list(v) for n, v in c.values.items()}
    for (name, k, is_curve), x in zip(slots, du[A.shape[1]:]):
        if is_curve:
            a = _magnitude(name, vals[name][0]) + x
            vals[name][0] = (1.0 - a) if name == "power_law" else a
        else:
            vals[name][k] = vals[name][k] + x
    return u_new, {n: tuple(float(x) for x in v) for n, v in vals.items()}


def _adequate(c: Candidate_, J_base_h: float, has_holdout: bool) -> bool:
    ok = c.J - 1.0 <= stats.null_quantile()
    if ok and has_holdout and math.isfinite(J_base_h):
        ok = (c.J_holdout < J_base_h and c.J_holdout - 1.0 <= stats.null_quantile(True))
    return bool(ok)


def _baseline_table(scenario: CellParams, u: np.ndarray) -> dict:
    vals = knob_values(scenario, {k.name: float(x) for k, x in zip(SHEET + CHAIN, u)})
    out = {}
    for k, x in zip(SHEET + CHAIN, u):
        out[k.name] = {"value": vals[k.name], "u": float(x), "tolerance": k.tolerance,
                       "relative": k.relative, "unit": k.unit, "outside": abs(float(x)) > 1 + 1e-9}
        if k in SHEET:
            from .baseline import written
            out[k.name]["written"] = written(scenario, k.name)
    return out


def _chain_correct(res, o: Outcome, u_c: np.ndarray):
    """``res`` with the chain's fitted errors removed (the fit's linear forms)."""
    dx, dz, bx, bz, g, lag = np.array([k.tolerance for k in CHAIN]) * np.asarray(u_c, float)
    prof = o.profile - o.normal @ np.array([dx, dz])
    force = None
    if o.force is not None:
        force = o.force - np.array([bx, bz]) - g * o.model_force + lag * o.model_dforce
    return replace(res, profile=prof, force=force)


def _as_res(d: RecordData, o: Outcome, run):
    from .compare import Residuals
    return Residuals(o.profile, o.arc, np.zeros((o.profile.size, 2)), o.force, o.delta_measured,
                     o.delta_model, run)


def process_figures(nominal: CellParams, corrected: CellParams,
                    d_candidates: Sequence[float] | None = None, delta_limit: float = 5e-3,
                    executor: Executor | None = None) -> dict:
    """Movement 4 of the nominal and the corrected cell: F_max [N], SF, Delta [m], d_opt [m].

    d_opt is the planner's choice (:func:`rheo_shaping.optimise.best_d`: smallest
    F_max with Delta <= ``delta_limit``) over ``d_candidates`` (default: the
    cell's d +- 3 mm in 1 mm steps); None when no candidate meets the limit.
    """
    from ..study.optimise import run_d
    d0 = nominal.movement.d
    ds = list(d_candidates) if d_candidates is not None else [d0 + k * 1e-3 for k in range(-3, 4)]
    jobs = [(p, d) for p in (nominal, corrected) for d in [d0] + ds]
    if executor is None:
        runs = [run_d(p, d) for p, d in jobs]
    else:
        runs = list(executor.map(_run_d, jobs))
    out = {}
    n = len(ds) + 1
    for i, key in enumerate(("nominal", "corrected")):
        rs = runs[i * n:(i + 1) * n]
        ok = [r for r in rs[1:] if math.isfinite(r.F_max) and r.delta <= delta_limit]
        best = min(ok, key=lambda r: (r.F_max, r.d)) if ok else None
        F = rs[0].F_max
        p = (nominal, corrected)[i]
        out[key] = {"F_max": F, "SF": p.material.F_break / F if F > 0 else math.inf,
                    "delta": rs[0].delta, "d_opt": best.d if best else None}
    return out


def _run_d(args):
    from ..study.optimise import run_d
    return run_d(*args)
