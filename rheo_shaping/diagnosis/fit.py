"""Fitting one effect (or a pair) to the fit records: bounded grid-and-refine search.

The objective is the noise-normalised misfit

    J = sum(r_p^2 / s_p^2 + |r_f|^2 / s_f^2) / (n_p + n_f)

over all fit records (profile residuals r_p, force residuals r_f, noise
levels s_p and s_f estimated from the records): J = 1 is a model that
agrees to within the noise.  The search works on u in [0, 1] mapped onto the
effect's bounds (squared toward the "off" end for effects that are off at a
bound, so small magnitudes are resolved), a grid of 6 points then two
refinements of 3 points around the best one (12 runs per record), each round
run in parallel; tool_offset (two parameters) takes a 5 x 5 grid and two 3 x 3
refinements.  The parameter's 95 % interval comes from the curvature of J at
the optimum, with the residual variance scaling the noise (a conservative
effective sample size: the number of profile frames).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..effects import EFFECTS, Effect
from .evaluate import Candidate, Evaluator


@dataclass(frozen=True)
class Misfit:
    """How to turn per-record stats into J."""

    sigma_p: float     # m
    sigma_f: float     # N
    records: tuple[int, ...]
    n_frames: int = 100   # effective sample size of the interval (profile frames)

    def J(self, stats_row) -> float:
        total, n = 0.0, 0
        for st in stats_row:
            c, k = st.chi2(self.sigma_p, self.sigma_f)
            total, n = total + c, n + k
        return total / n if n else math.inf


def _to_value(effect: Effect, k: int, u: float) -> float:
    lo, hi = effect.bounds[k]
    off = effect.off[k]
    if off <= lo:
        return lo + (hi - lo) * u * u
    if off >= hi:
        return hi - (hi - lo) * u * u
    return lo + (hi - lo) * u


@dataclass
class FitResult:
    """One candidate's fit: values, misfit on fit and holdout records, interval."""

    names: tuple[str, ...]
    values: dict                     # name -> tuple of values
    J: float
    J_holdout: float = math.nan
    interval: dict = field(default_factory=dict)   # name -> list of (lo, hi)
    runs: int = 0
    score: float = math.nan          # BIC (lower is better), set by the engine
    refined: bool = True             # False: the grid's best point only (not among the leaders)

    @property
    def candidate(self) -> Candidate:
        return tuple((n, self.values[n]) for n in self.names)

    @property
    def n_params(self) -> int:
        return sum(len(v) for v in self.values.values())


def grid_candidates(name: str, fixed: Candidate = ()) -> list:
    """The coarse grid of :func:`fit_effect` (to evaluate many effects in one parallel batch)."""
    effect = EFFECTS[name]
    dims = effect.n_params
    n_grid = GRID_1D if dims == 1 else GRID_2D
    axes = [np.linspace(0.0, 1.0, n_grid)] * dims
    pts = np.array(np.meshgrid(*axes, indexing="ij")).reshape(dims, -1).T
    return [fixed + ((name, tuple(_to_value(effect, k, float(u[k])) for k in range(dims))),) for u in pts]


GRID_1D, GRID_2D = 5, 4   # grid points per parameter (one, two parameters)


def fit_effect(name: str, ev: Evaluator, misfit: Misfit, fixed: Candidate = (),
               refine: bool = True) -> FitResult:
    """Fit one effect's parameters (other effects in ``fixed`` held).

    A grid over u in [0, 1] (6 points; 5 x 5 for two parameters, run in
    parallel), then a local search from the best grid point (Brent's bounded
    method on the bracketing grid cell; Nelder-Mead for two parameters; each
    evaluation runs the records in parallel), then the curvature of J from
    two neighbours per parameter at +-0.02 in u, which gives the interval.
    """
    from scipy.optimize import minimize, minimize_scalar

    effect = EFFECTS[name]
    dims = effect.n_params
    n_grid = GRID_1D if dims == 1 else GRID_2D
    step = 1.0 / (n_grid - 1)
    seen: dict = {}

    def cand(u) -> Candidate:
        vals = tuple(_to_value(effect, k, float(np.clip(u[k], 0, 1))) for k in range(dims))
        return fixed + ((name, vals),)

    def key(u) -> tuple:
        return tuple(float(x) for x in np.round(np.clip(np.atleast_1d(u), 0.0, 1.0), 9))

    def run(points) -> None:
        pts = list(dict.fromkeys(key(p) for p in points if key(p) not in seen))
        if not pts:
            return
        rows = ev.stats([cand(p) for p in pts], misfit.records)
        for p, row in zip(pts, rows):
            seen[p] = misfit.J(row)

    def J(u) -> float:
        run([u])
        v = seen[key(u)]
        return v if math.isfinite(v) else 1e30

    axes = [np.linspace(0.0, 1.0, n_grid)] * dims
    run(np.array(np.meshgrid(*axes, indexing="ij")).reshape(dims, -1).T)
    b = np.array(min(seen, key=seen.get))
    if not refine:
        values = cand(b)[-1][1]
        ivs = [tuple(sorted((_to_value(effect, k, max(0.0, b[k] - step)), _to_value(effect, k, min(1.0, b[k] + step)))))
               for k in range(dims)]
        return FitResult((name,), {name: values}, seen[key(b)], interval={name: ivs}, runs=len(seen),
                         refined=False)
    if dims == 1:
        lo, hi = max(0.0, b[0] - step), min(1.0, b[0] + step)
        minimize_scalar(lambda u: J([u]), bounds=(lo, hi), method="bounded",
                        options={"xatol": 3e-3, "maxiter": 10})
    else:
        simplex = [b, np.clip(b + [step / 2, 0], 0, 1), np.clip(b + [0, step / 2], 0, 1)]
        minimize(lambda u: J(np.clip(u, 0, 1)), b, method="Nelder-Mead",
                 options={"initial_simplex": simplex, "xatol": 3e-3, "fatol": 1e-4, "maxfev": 32})
    b = np.array(min(seen, key=seen.get))
    h = 0.02
    unit = np.eye(dims)
    run([np.clip(b + sgn * h * unit[k], 0, 1) for k in range(dims) for sgn in (-1.0, 1.0)])
    J_best = seen[key(b)]
    values = cand(b)[-1][1]
    interval = []
    for k in range(dims):
        lo_k, hi_k = key(b - h * unit[k]), key(b + h * unit[k])
        du = step
        if lo_k != key(b) and hi_k != key(b):
            a = (seen[lo_k] + seen[hi_k] - 2.0 * J_best) / (2.0 * h * h)
            if a > 0 and math.isfinite(a):
                du = math.sqrt(3.84 * J_best / (max(1, misfit.n_frames) * a))
        ends = sorted((_to_value(effect, k, max(0.0, b[k] - du)), _to_value(effect, k, min(1.0, b[k] + du))))
        interval.append((min(ends[0], values[k]), max(ends[1], values[k])))
    return FitResult((name,), {name: values}, J_best, interval={name: interval}, runs=len(seen))


def fit_pair(a: FitResult, b: FitResult, ev: Evaluator, misfit: Misfit) -> FitResult:  # noqa: D401
    """Two effects together: b refitted with a held, then a refitted with b held."""
    fb = fit_effect(b.names[0], ev, misfit, fixed=a.candidate)
    fa = fit_effect(a.names[0], ev, misfit, fixed=((b.names[0], fb.values[b.names[0]]),))
    names = (a.names[0], b.names[0])
    res = fa if fa.J <= fb.J else fb
    values = {a.names[0]: fa.values[a.names[0]] if fa.J <= fb.J else a.values[a.names[0]],
              b.names[0]: fb.values[b.names[0]]}
    return FitResult(names, values, min(fa.J, fb.J),
                     interval={a.names[0]: fa.interval[a.names[0]], b.names[0]: fb.interval[b.names[0]]},
                     runs=fa.runs + fb.runs + res.runs * 0)
