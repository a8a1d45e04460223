"""The diagnosis: where the model parts from the records, which effect causes it, how far the gap shrinks.

1. Noise.  The profile noise s_p [m] and force noise s_f [N] are estimated
   from the residuals of the nominal model (MAD of second differences along
   each frame, and in time: :func:`compare.noise_level`): a model that agrees
   leaves J = 1 (see :mod:`fit`).
2. Where.  The nominal residuals by place along the sheet, by phase and by
   observable, ranked by their systematic RMS sqrt(max(mean r^2 - s^2, 0))
   (:mod:`where`).
3. Which.  Every effect of the library fitted to the fit records
   (:func:`fit.fit_effect`: all on a coarse grid, the ``REFINED`` leaders
   refined); ranked by BIC = n ln J + k ln n (n: profile
   frames of the fit records, a conservative effective sample size since
   residuals are correlated along the sheet and in time; k: the effect's
   parameters), and scored on the holdout records with the fitted values.
   The verdict:

   * ``none`` when the nominal model already agrees within the noise
     (J0 - 1 <= ``NONE_EXCESS``);
   * the best effect when it explains at least ``EXPLAINED`` of the fit
     records' excess misfit (J0 - 1) and at least ``HOLDOUT_EXPLAINED`` of the
     holdout records' (when there are any), AND leaves no more than
     ``RESIDUAL_EXCESS`` (or ``RESIDUAL_FRACTION`` of J0 - 1) of excess: an
     effect that explains most but not all of a large gap is a substitute for
     one the library lacks, not the cause;
   * else the pair of the two best effects, under the same rule;
   * else ``unexplained``: no candidate accounts for the gap beyond noise.
4. How far.  Gap figures before (nominal) and after (the verdict's effect) on
   fit and holdout records (:mod:`gap`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from ..effects import EFFECT_NAMES
from ..record import Record
from .compare import RecordData, noise_level, residuals, simulate
from .evaluate import Evaluator, apply
from .fit import FitResult, Misfit, fit_effect, fit_pair, grid_candidates

NONE_EXCESS = 0.06        # J0 - 1 at or below this: the model agrees within noise
EXPLAINED = 0.9           # fraction of the fit records' excess misfit the verdict must explain
HOLDOUT_EXPLAINED = 0.75  # ... and of the holdout records'
RESIDUAL_EXCESS = 0.18    # J - 1 the verdict may leave (a systematic gap of 0.42 x the noise) ...
RESIDUAL_FRACTION = 0.05  # ... or this fraction of J0 - 1 (twice it on the holdout), whichever is larger
REFINED = 3               # effects refined beyond their grid (the leaders by grid misfit)
PAIRED = 2                # pairs are tried among this many best effects


@dataclass
class Diagnosis:
    """Everything the report and the JSON say."""

    verdict: str
    verdict_fit: FitResult | None
    effects: list[FitResult]
    pairs: list[FitResult]
    where: list[dict]
    gap_before: dict
    gap_after: dict
    noise: dict
    J0: float
    J0_holdout: float
    records: list[str]
    holdout: list[str]
    runs: int
    residual_maps: list = field(default_factory=list)   # for the figures

    def explained(self, fr: FitResult, holdout: bool = False) -> float:
        J0 = self.J0_holdout if holdout else self.J0
        J = fr.J_holdout if holdout else fr.J
        if not (math.isfinite(J0) and math.isfinite(J)) or J0 - 1.0 <= 0:
            return math.nan
        return (J0 - J) / (J0 - 1.0)

    def to_json(self) -> dict:
        def eff(fr: FitResult, rank: int) -> dict:
            return {"name": "+".join(fr.names), "rank": rank, "refined": fr.refined,
                    "params": {n: list(v) for n, v in fr.values.items()},
                    "interval": {n: [list(iv) for iv in ivs] for n, ivs in fr.interval.items()},
                    "score": fr.score, "J_fit": fr.J, "J_holdout": _num(fr.J_holdout),
                    "explained_fit": _num(self.explained(fr)),
                    "explained_holdout": _num(self.explained(fr, True))}
        ranked = sorted(self.effects + self.pairs, key=lambda f: f.score)
        out = {"verdict": self.verdict,
               "verdict_params": ({n: list(v) for n, v in self.verdict_fit.values.items()}
                                  if self.verdict_fit else None),
               "verdict_interval": ({n: [list(iv) for iv in ivs] for n, ivs in self.verdict_fit.interval.items()}
                                    if self.verdict_fit else None),
               "effects": [eff(f, i + 1) for i, f in enumerate(ranked)],
               "where": self.where, "gap_before": self.gap_before, "gap_after": self.gap_after,
               "noise": self.noise, "J_nominal": {"fit": self.J0, "holdout": _num(self.J0_holdout)},
               "records": self.records, "holdout": self.holdout, "simulations": self.runs}
        return out


def _num(v):
    return None if v is None or not math.isfinite(v) else float(v)


def diagnose(records: Sequence[Record], holdout: Sequence[Record] = (),
             library: Sequence[str] = EFFECT_NAMES, jobs: int | None = None,
             progress: Callable[[int], None] | None = None) -> Diagnosis:
    """Diagnose the gap between ``records`` (fitted) and their nominal model; check on ``holdout``."""
    from . import gap, where as where_mod
    if not records:
        raise ValueError("diagnose needs at least one record to fit")
    data = [RecordData.of(r) for r in list(records) + list(holdout)]
    fit_idx = tuple(range(len(records)))
    hold_idx = tuple(range(len(records), len(data)))
    # nominal residuals: noise levels and where
    nominal_runs = [simulate(d.record.scenario, d) for d in data]
    nominal_res = [residuals(d, run) for d, run in zip(data, nominal_runs)]
    sp = float(np.nanmedian([noise_level(r.profile, d.point_frame) for d, r in zip(data, nominal_res)]))
    sfs = [noise_level(r.force[:, k]) for r in nominal_res if r.force is not None for k in (0, 1)]
    sf = float(np.nanmedian(sfs)) if sfs else math.nan
    if not (sp > 0):
        raise ValueError("the records' profile noise cannot be estimated (too few points per frame)")
    sf = sf if sf > 0 else 1.0
    frames = sum(len(data[i].record.profile_t) for i in fit_idx)
    misfit = Misfit(sp, sf, fit_idx, frames)
    hold = Misfit(sp, sf, hold_idx, sum(len(data[i].record.profile_t) for i in hold_idx))
    with Evaluator(data, jobs, progress) as ev:
        J0 = misfit.J(ev.stats([()], fit_idx)[0])
        J0h = hold.J(ev.stats([()], hold_idx)[0]) if hold_idx else math.nan
        fits = []
        if J0 - 1.0 > NONE_EXCESS:
            # every effect's grid in one parallel batch, then refine the leaders only
            ev.stats([c for name in library for c in grid_candidates(name)], fit_idx)
            coarse = {name: fit_effect(name, ev, misfit, refine=False) for name in library}
            leaders = sorted(coarse, key=lambda n: coarse[n].J)[:REFINED]
            fits = [fit_effect(name, ev, misfit) if name in leaders else coarse[name] for name in library]
        _score(fits, ev, hold, frames)
        diag = Diagnosis("none", None, fits, [], [], {}, {}, {"profile_m": sp, "force_N": sf},
                         J0, J0h, [d.record.name for d in data[:len(records)]],
                         [d.record.name for d in data[len(records):]], 0)
        verdict_fit = None
        if J0 - 1.0 > NONE_EXCESS:
            ranked = sorted(fits, key=lambda f: f.score)
            verdict_fit = next((f for f in ranked[:1] if _accepts(diag, f)), None)
            if verdict_fit is None and len(ranked) >= 2:
                top = ranked[:PAIRED]
                pairs = [fit_pair(a, b, ev, misfit) for i, a in enumerate(top) for b in top[i + 1:]]
                _score(pairs, ev, hold, frames)
                diag.pairs = pairs
                best_pair = min(pairs, key=lambda f: f.score)
                if _accepts(diag, best_pair):
                    verdict_fit = best_pair
            diag.verdict = "+".join(verdict_fit.names) if verdict_fit else "unexplained"
        diag.verdict_fit = verdict_fit
        after = verdict_fit.candidate if verdict_fit else ()
        after_runs = [simulate(apply(d.record.scenario, after), d) if after else run
                      for d, run in zip(data, nominal_runs)]
        after_res = [residuals(d, run) for d, run in zip(data, after_runs)]
        diag.runs = ev.runs + 2 * len(data)
    diag.where = where_mod.rank(data[:len(records)], nominal_res[:len(records)], nominal_runs[:len(records)], sp, sf)
    diag.gap_before = gap.figures(data, nominal_res, fit_idx, hold_idx, sp, sf)
    diag.gap_after = gap.figures(data, after_res, fit_idx, hold_idx, sp, sf, before=diag.gap_before)
    diag.residual_maps = [(d, nominal_res[i], after_res[i], nominal_runs[i]) for i, d in enumerate(data)]
    return diag


def _score(fits: list[FitResult], ev: Evaluator, hold: Misfit, frames: int) -> None:
    n = max(frames, 2)
    for f in fits:
        f.score = n * math.log(max(f.J, 1e-12)) + f.n_params * math.log(n)
    if hold.records:
        rows = ev.stats([f.candidate for f in fits], hold.records)
        for f, row in zip(fits, rows):
            f.J_holdout = hold.J(row)


def _accepts(diag: Diagnosis, f: FitResult) -> bool:
    """Named only when it explains the gap nearly completely, on the fit and the holdout records."""
    ok = (diag.explained(f) >= EXPLAINED
          and f.J - 1.0 <= max(RESIDUAL_EXCESS, RESIDUAL_FRACTION * (diag.J0 - 1.0)))
    if ok and diag.holdout and math.isfinite(diag.J0_holdout) and diag.J0_holdout - 1.0 > NONE_EXCESS:
        ok = (diag.explained(f, True) >= HOLDOUT_EXPLAINED
              and f.J_holdout - 1.0 <= max(RESIDUAL_EXCESS, 2 * RESIDUAL_FRACTION * (diag.J0_holdout - 1.0)))
    return bool(ok)
