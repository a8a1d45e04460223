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

    @property
    def candidate(self) -> Candidate:
        return tuple((n, self.values[n]) for n in self.names)

    @property
    def n_params(self) -> int:
        return sum(len(v) for v in self.values.values())


def fit_effect(name: str, ev: Evaluator, misfit: Misfit, fixed: Candidate = ()) -> FitResult:
    """Fit one effect's parameters (other effects in ``fixed`` held)."""
    effect = EFFECTS[name]
    dims = effect.n_params
    n_grid, n_ref = (6, 3) if dims == 1 else (5, 3)
    axes = [np.linspace(0.0, 1.0, n_grid) for _ in range(dims)]
    step = 1.0 / (n_grid - 1)
    seen: dict = {}

    def cand(u) -> Candidate:
        vals = tuple(_to_value(effect, k, float(np.clip(u[k], 0, 1))) for k in range(dims))
        return fixed + ((name, vals),)

    def run(points) -> None:
        pts = [tuple(np.round(p, 10)) for p in points if tuple(np.round(p, 10)) not in seen]
        if not pts:
            return
        rows = ev.stats([cand(p) for p in pts], misfit.records)
        for p, row in zip(pts, rows):
            seen[p] = misfit.J(row)

    grid = np.array(np.meshgrid(*axes, indexing="ij")).reshape(dims, -1).T
    run(grid)
    for _ in range(2):
        best = np.array(min(seen, key=seen.get))
        step *= 2.0 / (n_ref + 1)
        offs = np.array(np.meshgrid(*[np.arange(-(n_ref // 2), n_ref // 2 + 1)] * dims, indexing="ij")).reshape(dims, -1).T
        run([np.clip(best + o * step, 0, 1) for o in offs if np.any(o != 0)])
    best = np.array(min(seen, key=seen.get))
    J_best = seen[tuple(best)]
    values = cand(best)[-1][1]
    interval = _interval(effect, best, seen, misfit, step)
    return FitResult((name,), {name: values}, J_best, interval={name: interval}, runs=len(seen))


def _interval(effect: Effect, best: np.ndarray, seen: dict, misfit: Misfit, step: float) -> list:
    """95 % interval per parameter from a parabola through J along each axis."""
    J0 = seen[tuple(best)]
    n_eff = max(1, misfit.n_frames)
    out = []
    for k in range(len(best)):
        pts = [(p[k], J) for p, J in seen.items()
               if np.allclose(np.delete(np.array(p), k), np.delete(best, k)) and math.isfinite(J)]
        pts.sort()
        us = np.array([p[0] for p in pts])
        Js = np.array([p[1] for p in pts])
        near = np.argsort(np.abs(us - best[k]))[:3]
        lo_u, hi_u = 0.0, 1.0
        if near.size == 3 and np.ptp(us[near]) > 0:
            a = np.polyfit(us[near], Js[near], 2)[0]
            if a > 0:
                # chi2 = n_eff J / J0 rises by 3.84 (95 %) at du = sqrt(3.84 J0 / (n_eff a))
                du = math.sqrt(3.84 * J0 / (n_eff * a))
                lo_u, hi_u = max(0.0, best[k] - du), min(1.0, best[k] + du)
        vals = sorted((_to_value(effect, k, lo_u), _to_value(effect, k, hi_u)))
        v_best = _to_value(effect, k, best[k])
        out.append((min(vals[0], v_best), max(vals[1], v_best)))
    return out


def fit_pair(a: FitResult, b: FitResult, ev: Evaluator, misfit: Misfit) -> FitResult:
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
