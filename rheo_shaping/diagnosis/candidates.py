"""Candidate explanations: the effects' probes, their linearised fits (single and pairs)."""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from ..sheet.effects import EFFECTS
from . import stats
from .evaluate import Candidate
from .linear import Solver, Stack

#: Probe values per effect: (kind, values).  "curve": a scalar effect probed at two magnitudes,
#: the response piecewise linear through 0 and both; "linear": one column per probe (signed),
#: a parameter probed on both sides taking the column of the side its value lies on
#: (:func:`linear_sides`, :func:`side_columns`).  The tool offset is probed on both sides of
#: each axis: a tool pressing deeper than written meets the contact, one held higher leaves
#: it, and a column from one side continued through zero sent a deep offset's search the
#: wrong way.
PROBES: dict = {
    "friction_mould": ("curve", (0.2, 0.5), 0.8),
    "friction_tool": ("curve", (0.2, 0.5), 0.8),
    "bending": ("curve", (3e-6, 1e-5), 1.6e-5),
    "kelvin_c1": ("curve", (500.0, 2000.0), 3000.0),
    "power_law": ("curve", (0.8, 0.55), 0.35),
    "thinning": ("curve", (0.6, 1.6), 2.5),
    "tool_offset": ("linear", ((1e-3, 0.0), (0.0, 1e-3), (-1e-3, 0.0), (0.0, -1e-3)), None),
    "mass_error": ("linear", ((0.25,),), None),
}
GRID = 41          # magnitudes tried per curve effect on the linearised model
CHECKED = 2        # single effects checked by simulation
PAIRED = 3         # pairs among this many best single effects
REFINE_STEPS = 8   # chord (secant) steps of each checked candidate (each simulated)


@dataclass
class Search:
    """Where a candidate's point search stands (not evidence): its last simulated run's
    residuals, its own Jacobian of the sheet knobs, the point before, the step factor."""

    z_raw: np.ndarray | None = None         # fit records' z at the last run (chain uncorrected)
    zh_raw: np.ndarray | None = None        # holdout records' z, same run
    jacobian: np.ndarray | None = None      # own sheet-knob Jacobian (:func:`check.relinearise`)
    prev: tuple | None = None               # (z_raw, u_sheet, values) of the point before
    damp: float = 1.0                       # step factor (halved on a miss)
    converged: bool = False                 # :func:`converge.converge` refined it to the end
    first_J: float = math.nan               # J of its linearised first fit (before any run)

    @property
    def simulated_z(self) -> np.ndarray:
        """``z_raw`` of a candidate simulated once at least (:func:`check.check` sets it)."""
        if self.z_raw is None:
            raise ValueError("candidate not simulated yet: no residual to step from")
        return self.z_raw


@dataclass
class Explanation:
    """One candidate explanation (an effect or a pair) and its evidence; ``search``: the
    state of its refinement."""

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
    J_num: float = math.nan         # misfit of its run against the refined run (fit records)
    J_num_holdout: float = math.nan
    refinement: str = "chain and steps"   # what numerics() refined
    J_num_perp: float = math.nan    # the part of J_num no refit absorbs
    J_num_added: float = math.nan   # misfit of its refinement change less the baseline's (fit)
    J_num_added_holdout: float = math.nan
    value_shift: dict = field(default_factory=dict)  # name -> value shift under refinement
    search: Search = field(default_factory=Search, repr=False)

    @property
    def fitted_u(self) -> np.ndarray:
        """``baseline_u`` of a fitted explanation (every fit and the baseline set it)."""
        if self.baseline_u is None:
            raise ValueError(f"explanation {self.names}: no baseline fit")
        return self.baseline_u

    @property
    def candidate(self) -> Candidate:
        return tuple((n, self.values[n]) for n in self.names)

    @property
    def n_params(self) -> int:
        return self.k


@dataclass(frozen=True)
class LinearFit:
    """The linearised model at the calibrated baseline, what :func:`fit_single` and
    :func:`fit_pair` read: the baseline's residual ``z`` (chain uncorrected), the bounded
    solver on [sheet Jacobian, chain columns] and its bounds, how the residual splits by
    observable (``stack``), the effective sample sizes and the baseline's misfit parts."""

    z: np.ndarray
    solver: Solver
    lo: np.ndarray
    hi: np.ndarray
    stack: Stack
    n_eff: dict
    parts: dict


def rank_key(f: Explanation):
    return (not f.checked, f.p if math.isfinite(f.p) else 1.0, f.J)


def response_at(resp, a: float) -> np.ndarray:
    """Piecewise-linear response at magnitude ``a`` through (0, 0) and the probes."""
    (m1, d1), (m2, d2) = resp
    if a <= m1:
        return d1 * (a / m1)
    return d1 + (d2 - d1) * ((a - m1) / (m2 - m1))


def magnitude(name: str, v: float) -> float:
    return 1.0 - v if name == "power_law" else v


def curve_probes(name: str, resp) -> list[tuple[float, np.ndarray]]:
    """A curve effect's (magnitude, response) pairs for :func:`response_at`, from its probes
    that ran ((values, response) pairs, at least one): with one probe only, the line
    through it continued to twice its magnitude."""
    mags = [(magnitude(name, v[0]), d) for v, d in resp]
    if len(mags) < 2:
        mags = [mags[0], (2 * mags[0][0], 2 * mags[0][1])]
    return mags


def _side_of(v) -> tuple[int, float]:
    """The parameter a linear probe ``v`` moves (its largest entry) and the side (+-1)."""
    k = int(np.argmax(np.abs(v)))
    return k, (1.0 if v[k] > 0 else -1.0)


def _by_side(resp) -> dict[int, dict[float, np.ndarray]]:
    """A linear effect's probe responses per unit, by parameter and side."""
    by_k: dict[int, dict[float, np.ndarray]] = {}
    for v, d in resp:
        k, side = _side_of(v)
        by_k.setdefault(k, {})[side] = d / v[k]
    return by_k


def linear_sides(name: str, resp) -> list[list[tuple[int, np.ndarray, float, float]]]:
    """A linear effect's fits to try (:func:`fit_single`, :func:`fit_pair`): each a choice of
    one column per parameter, as (parameter index, response per unit, lower bound, upper
    bound).  A parameter probed on both sides gives two choices, its positive side's column
    within [0, hi] and its negative side's within [lo, 0] (the response piecewise linear
    through zero); one probed on one side only, its column within the effect's bounds."""
    e = EFFECTS[name]
    by_k = _by_side(resp)
    options = []
    for k in sorted(by_k):
        lo, hi = e.bounds[k]
        sides = by_k[k]
        if len(sides) == 1:
            options.append([(k, next(iter(sides.values())), lo, hi)])
        else:
            options.append([(k, sides[1.0], max(lo, 0.0), hi),
                            (k, sides[-1.0], lo, min(hi, 0.0))])
    return [list(c) for c in itertools.product(*options)]


def side_columns(name: str, resp, value) -> list[tuple[int, np.ndarray]]:
    """A linear effect's columns at ``value``: per parameter, the column of the side its value
    lies on (the positive side at zero), or of the one side it was probed on."""
    by_k = _by_side(resp)
    out = []
    for k in sorted(by_k):
        sides = by_k[k]
        want = -1.0 if k < len(value) and value[k] < 0 else 1.0
        out.append((k, sides.get(want, next(iter(sides.values())))))
    return out


def fit_single(name: str, resp, lin: LinearFit) -> Explanation | None:
    """Effect ``name`` fitted jointly with the baseline's knobs on the linearised model
    ``lin``, from its probe responses ``resp`` ((values, response or None) pairs): a linear
    effect by its columns, a curve effect on a grid of magnitudes (the response piecewise
    linear through 0 and its probes); with its 95 % interval and likelihood ratio.  None
    when no probe ran."""
    kind, vals, top = PROBES[name]
    e = EFFECTS[name]
    solver, n_eff = lin.solver, lin.n_eff
    if any(d is None for _, d in resp):
        resp = [(v, d) for v, d in resp if d is not None]
        if not resp:
            return None
    if kind == "linear":
        best = None
        for option in linear_sides(name, resp):
            E = np.column_stack([col for _, col, _, _ in option])
            elo = np.array([lo for _, _, lo, _ in option])
            ehi = np.array([hi for _, _, _, hi in option])
            u, J = solver.solve(lin.z, lin.lo, lin.hi, E, (elo, ehi))
            if best is None or J < best[0]:
                best = (J, u, E, option)
        assert best is not None         # a probe ran: one option at least
        J, u, E, option = best
        vals_fit = [0.0] * e.n_params
        for (k, _, _, _), x in zip(option, u[solver.A.shape[1]:]):
            vals_fit[k] = float(x)
        z = solver.residual(lin.z, u, E)
        c = Explanation((name,), {name: tuple(vals_fit)}, J, lin.stack.J_parts(z),
                        k=len(option), baseline_u=u[:solver.A.shape[1]])
        # 95 % interval: the value whose LR drop is 3.84 (effective sample size), the baseline
        # refitted (the column with the baseline's columns projected out)
        e_perp = E - solver.Q @ (solver.Q.T @ E)
        ntot = sum(n_eff.values())
        ivs = [(v, v) for v in vals_fit]
        for (k, _, _, _), col in zip(option, e_perp.T):
            h = float(col @ col)
            half = math.sqrt(3.84 * J / (ntot * h)) if h > 0 else math.inf
            ivs[k] = (vals_fit[k] - half, vals_fit[k] + half)
        c.interval = {name: ivs}
    else:
        mags = curve_probes(name, resp)
        grid = np.linspace(0.0, magnitude(name, top), GRID)
        Js, us = [], []
        for a in grid:
            u, J = solver.solve(lin.z + response_at(mags, a), lin.lo, lin.hi)
            Js.append(J)
            us.append(u)
        i = int(np.argmin(Js))
        a = float(grid[i])
        # 95 % interval: magnitudes within the LR drop of 3.84 (effective sample size)
        ntot = sum(n_eff.values())
        lo_a, hi_a = lr_interval(grid, np.asarray(Js), i, ntot)
        z = lin.z + response_at(mags, a) + solver.A @ us[i]
        v = 1.0 - a if name == "power_law" else a
        iv = sorted((1.0 - lo_a, 1.0 - hi_a)) if name == "power_law" else [lo_a, hi_a]
        c = Explanation((name,), {name: (v,)}, Js[i], lin.stack.J_parts(z), k=1,
                        baseline_u=us[i])
        c.interval = {name: [tuple(iv)]}
    c.LR = stats.likelihood_ratio(lin.parts, c.J_parts, n_eff)
    return c


def lr_interval(grid: np.ndarray, Js: np.ndarray, i: int, ntot: float) -> tuple[float, float]:
    """Magnitudes whose LR drop n ln(J / J_min) stays within 3.84 (95 %), between grid points
    by linear interpolation of the drop, and never narrower than the parabola through the
    minimum and its neighbours gives (a grid step can be wider than the interval)."""
    drop = ntot * np.log(Js / Js[i])
    lo_a = hi_a = float(grid[i])
    j = i
    while j > 0 and drop[j - 1] <= 3.84:
        j -= 1
    lo_a = float(grid[j]) if j == 0 else float(np.interp(3.84, [drop[j], drop[j - 1]],
                                                         [grid[j], grid[j - 1]]))
    j = i
    while j < len(grid) - 1 and drop[j + 1] <= 3.84:
        j += 1
    hi_a = float(grid[j]) if j == len(grid) - 1 else float(np.interp(3.84, [drop[j], drop[j + 1]],
                                                                     [grid[j], grid[j + 1]]))
    if 0 < i < len(grid) - 1:
        h = float(grid[1] - grid[0])
        curv = (drop[i - 1] - 2 * drop[i] + drop[i + 1]) / h ** 2
        if curv > 0:
            half = math.sqrt(2 * 3.84 / curv)
            lo_a, hi_a = min(lo_a, float(grid[i]) - half), max(hi_a, float(grid[i]) + half)
    return max(lo_a, float(grid[0])), min(hi_a, float(grid[-1]))


def fit_pair(a: Explanation, b: Explanation, responses, lin: LinearFit) -> Explanation:
    """Two effects together on the linearised model ``lin`` (responses add): linear effects
    by their columns, curve effects on a grid of 17 magnitudes each."""
    na, nb = a.names[0], b.names[0]
    solver = lin.solver
    best = None
    # per effect (name, kind, probes): linear, its (values, response) pairs; curve, its
    # (magnitude, response) pairs and the magnitudes tried
    curve: list[tuple[str, str, tuple[list[tuple[float, np.ndarray]], np.ndarray]]] = []
    lin_e: list[tuple[str, str, list[tuple[tuple[float, ...], np.ndarray]]]] = []
    for n in (na, nb):
        kind, vals, top = PROBES[n]
        resp = [(v, d) for v, d in responses[n] if d is not None]
        if kind == "linear":
            lin_e.append((n, "linear", resp))
        else:
            grid = np.linspace(0, magnitude(n, top), 17)
            curve.append((n, "curve", (curve_probes(n, resp), grid)))
    # each choice of sides of the linear effects (:func:`linear_sides`): columns, bounds,
    # (effect, parameter) per column
    choices: list[tuple[np.ndarray | None, list, list, list]] = []
    for sides in itertools.product(*[linear_sides(n, resp) for n, _, resp in lin_e]):
        cols, elo, ehi, kidx = [], [], [], []
        for (n, _, _), option in zip(lin_e, sides):
            for k, col, lo, hi in option:
                cols.append(col)
                elo.append(lo)
                ehi.append(hi)
                kidx.append((n, k))
        choices.append((np.column_stack(cols) if cols else None, elo, ehi, kidx))
    # one combination of curve magnitudes each (without curve effects: one, the empty one)
    for combo in itertools.product(*[g[2][1] for g in curve]):
        shift = np.zeros_like(lin.z)
        for (n, _, (mags, _g)), x in zip(curve, combo):
            shift = shift + response_at(mags, x)
        for E, elo, ehi, kidx in choices:
            u, J = solver.solve(lin.z + shift, lin.lo, lin.hi, E,
                                (np.array(elo), np.array(ehi)) if E is not None else None)
            if best is None or J < best[0]:
                best = (J, u, combo, shift, E, kidx)
    assert best is not None         # the product of non-empty grids has a combination
    J, u, combo, shift, E, kidx = best
    values: dict[str, tuple[float, ...]] = {}
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
    z = lin.z + shift + solver.A @ u[:k0] + (E @ u[k0:] if E is not None else 0.0)
    names = tuple(sorted((na, nb)))
    c = Explanation(names, {n: values[n] for n in names}, J, lin.stack.J_parts(z),
                    k=a.k + b.k, baseline_u=u[:solver.A.shape[1]])
    c.interval = {n: [(v, v) for v in values[n]] for n in names}
    c.LR = stats.likelihood_ratio(lin.parts, c.J_parts, lin.n_eff)
    return c
