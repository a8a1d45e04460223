"""What a diagnosis says: the :class:`Verdict`, the :class:`Diagnosis` and its JSON, and the
corrected cell's process figures."""
from __future__ import annotations

import math
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import Sequence

import numpy as np

from ..params.cell import CellParams
from ..sheet.metrics import safety_factor
from .baseline import CHAIN, SHEET, values as knob_values
from .candidates import Explanation, rank_key
from .compare import RecordData
from .evaluate import Outcome
from .figures import FloorReport, GapGroups, Noise
from .options import BaselineMode


class Verdict(StrEnum):
    """What a diagnosis says (its value is the JSON's ``verdict`` where it names no effect)."""

    NONE = "none"                           # no gap beyond the floor (or the tolerance)
    EFFECT = "effect"                       # one library effect explains it
    PAIR = "pair"                           # two library effects together explain it
    MEASUREMENT_CHAIN = "measurement chain"  # the chain beyond its tolerances explains it
    UNEXPLAINED = "unexplained"             # a gap nothing of the library explains


@dataclass(frozen=True, kw_only=True)
class Diagnosis:
    """Everything the report and the JSON say (:func:`~.engine.diagnose`)."""

    verdict: Verdict
    named: tuple[str, ...] = ()     # the effect or the pair's effects (EFFECT, PAIR)
    verdict_fit: Explanation | None  # the named explanation (EFFECT, PAIR)
    effects: list[Explanation]      # each library effect's candidate
    pairs: list[Explanation]        # the pairs tried (none unless no single one explains)
    where: list[dict]               # observables and phases, largest remainder first
    gap_before: GapGroups           # the nominal model's gap figures
    gap_baseline: GapGroups         # the calibrated baseline's
    gap_after: GapGroups            # the verdict's (the baseline's when it names nothing)
    noise: Noise
    J0: float                       # nominal balanced misfit, fit records (1: noise)
    J0_holdout: float
    J_base: float                   # calibrated baseline's, fit records
    J_base_holdout: float
    baseline: dict                  # knob -> {value, written, u, tolerance, unit, outside}
    side: dict                      # {"side": ..., "p_chain": ..., "chain_outside": [...]}
    p_gap: float                    # the gap test's p-value
    n_eff: dict                     # effective sample sizes
    records: list[str]              # fit records' names
    holdout: list[str]              # holdout records' names
    runs: int                       # simulations run
    floor: FloorReport              # the floor the verdict was judged against
    initial_state: dict             # how each record's model started (initial_state.py)
    baseline_mode: BaselineMode = BaselineMode.CALIBRATED
    signature: dict | None = None   # the residual's signature (a gap left unnamed)
    corrected: CellParams | None = None
    residual_maps: list = field(default_factory=list)
    numerics_base: Explanation | None = None   # the baseline's run against its refined run
    J_replay: tuple = (None, None)   # draws of the model's own replay misfit (fit, holdout)

    @property
    def verdict_name(self) -> str:
        """The verdict in words: the effect (``a+b`` for a pair), else the verdict's value."""
        return "+".join(self.named) if self.named else self.verdict.value

    def explained(self, fr: Explanation, holdout: bool = False) -> float:
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

    def baseline_took_text(self) -> str:
        """What the calibrated baseline did to the nominal model's misfit, in words: a
        share of the excess misfit, or, where the nominal model had none (J0 <= 1: it fits
        within the noise, as a record of the cell's own model does), that it had none."""
        if not (math.isfinite(self.J0) and math.isfinite(self.J_base)):
            return "the misfit could not be computed"
        if self.J0 <= 1.0:
            return (f"the nominal model already fits within the noise (J - 1 = "
                    f"{self.J0 - 1.0:.4f} <= 0): no excess misfit for the baseline to take "
                    f"(baseline J - 1 = {self.J_base - 1.0:.4f})")
        return (f"the baseline took {100 * self.baseline_took:.1f} % of the nominal model's "
                f"excess misfit (J - 1: {self.J0 - 1.0:.4f} -> {self.J_base - 1.0:.4f})")

    def to_json(self) -> dict:
        def eff(fr: Explanation, rank: int) -> dict:
            return {"name": "+".join(fr.names), "rank": rank, "checked": fr.checked,
                    "params": {n: list(v) for n, v in fr.values.items()},
                    "interval": {n: [list(iv) for iv in ivs] for n, ivs in fr.interval.items()},
                    "J_fit": fr.J, "J_holdout": num(fr.J_holdout), "LR": num(fr.LR),
                    "p": num(fr.p), "adequate": fr.adequate,
                    "explained_fit": num(self.explained(fr)),
                    "explained_holdout": num(self.explained(fr, True)),
                    "J_numerics": {"fit": num(fr.J_num), "fit_unabsorbed": num(fr.J_num_perp),
                                   "holdout": num(fr.J_num_holdout),
                                   "added": num(fr.J_num_added),
                                   "added_holdout": num(fr.J_num_added_holdout),
                                   "refined": fr.refinement},
                    "value_shift_refined": fr.value_shift}
        ranked = sorted(self.effects + self.pairs, key=rank_key)
        vf = self.verdict_fit
        return {"verdict": self.verdict_name,
                "verdict_params": {n: list(v) for n, v in vf.values.items()} if vf else None,
                "verdict_interval": ({n: [list(iv) for iv in ivs]
                                      for n, ivs in vf.interval.items()}
                                     if vf else None),
                "verdict_p": num(vf.p) if vf else None,
                "p_gap": self.p_gap, "side": self.side, "baseline": self.baseline,
                "baseline_took": num(self.baseline_took),
                "J_nominal": {"fit": self.J0, "holdout": num(self.J0_holdout)},
                "J_baseline": {"fit": self.J_base, "holdout": num(self.J_base_holdout)},
                "J_replay": {k: (None if v is None else [float(x) for x in v])
                             for k, v in zip(("fit", "holdout"), self.J_replay)},
                "n_eff": self.n_eff, "effects": [eff(f, i + 1) for i, f in enumerate(ranked)],
                "signature": self.signature, "where": self.where,
                "gap_before": self.gap_before.as_json(),
                "gap_baseline": self.gap_baseline.as_json(),
                "gap_after": self.gap_after.as_json(), "noise": self.noise.as_json(),
                "records": self.records,
                "holdout": self.holdout, "simulations": self.runs,
                "J_numerics_baseline": self.numerics_json(),
                "initial_state": _finite(self.initial_state),
                "floor": _finite(self.floor.as_json()),
                "baseline_mode": self.baseline_mode.value}

    def numerics_json(self) -> dict | None:
        """The baseline's numerics misfit (None when no candidate was checked)."""
        b = self.numerics_base
        if b is None:
            return None
        return {"fit": num(b.J_num), "fit_unabsorbed": num(b.J_num_perp),
                "holdout": num(b.J_num_holdout)}


def _finite(x):
    """``x`` with every non-finite float as None (plain JSON)."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    return x


def num(v):
    return None if v is None or not math.isfinite(v) else float(v)


def baseline_table(scenario: CellParams, u: np.ndarray, sheet_lim: float = 1.0) -> dict:
    vals = knob_values(scenario, {k.name: float(x) for k, x in zip(SHEET + CHAIN, u)},
                       sheet_lim)
    out = {}
    for k, x in zip(SHEET + CHAIN, u):
        inside = k.lower - 1e-9 <= float(x) <= k.upper + 1e-9
        out[k.name] = {"value": vals[k.name], "u": float(x), "tolerance": k.tolerance,
                       "relative": k.relative, "unit": k.unit, "outside": not inside}
        if k in SHEET:
            from .baseline import written
            out[k.name]["written"] = written(scenario, k.name)
    return out


def chain_correct(res, o: Outcome, u_c: np.ndarray):
    """``res`` with the chain's fitted errors removed (the fit's linear forms)."""
    dx, dz, bx, bz, g, lag = np.array([k.tolerance for k in CHAIN]) * np.asarray(u_c, float)
    prof = o.profile - o.normal @ np.array([dx, dz])
    force = None
    if o.force is not None:
        force = o.force - np.array([bx, bz]) - g * o.model_force + lag * o.model_dforce
    return replace(res, profile=prof, force=force)


def as_residuals(d: RecordData, o: Outcome, run):
    from .compare import Residuals
    profile = o.array("profile")
    return Residuals(profile, o.array("arc"), np.zeros((profile.size, 2)), o.force,
                     o.delta_measured, o.delta_model, run)


def process_figures(nominal: CellParams, corrected: CellParams,
                    d_candidates: Sequence[float] | None = None, delta_limit: float = 5e-3,
                    executor: Executor | None = None) -> dict:
    """Movement 4 of the nominal and the corrected cell: F_max [N], SF, Delta [m], d_opt [m].

    d_opt is the planner's choice (:func:`rheo_shaping.planning.choose_d.best_d`: smallest
    F_max with Delta <= ``delta_limit``) over ``d_candidates`` (default: the
    cell's d +- 3 mm in 1 mm steps); None when no candidate meets the limit.
    """
    from ..planning.choose_d import run_d
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
        out[key] = {"F_max": F, "SF": safety_factor(p.material.F_break, F),
                    "delta": rs[0].delta, "d_opt": best.d if best else None}
    return out


def _run_d(args):
    from ..planning.choose_d import run_d
    return run_d(*args)
