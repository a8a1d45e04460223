"""Validation of the diagnosis on withheld effects (``rheo-shaping diagnose-benchmark``).

Each case is a true cell: the default cell with one effect (most cases), two
effects, or none, at a magnitude drawn from the effect's realistic range
(``Effect.realistic``; random sign for tool_offset components and
mass_error), recorded on three runs of different movements (1-4, drawn
without replacement) with the default measurement model and their own noise
seeds.  The diagnosis fits the first two and holds out the third; it sees only
the records (scenario = nominal cell), never the truth.  Out-of-library cases
have one true effect that is removed from the diagnosis's library.  A drawn
case whose true run would tear the sheet (F_max >= F_break) or fails to run
is redrawn (no real record exists of it).

Scores (fractions in 0..1):

* ``top1_accuracy``: single in-library cases whose verdict names the true effect;
* ``param_rel_error_median``: |fitted - true| / |true| of those (vector norm for tool_offset);
* ``no_effect_false_name_rate``: no-effect cases whose verdict names an effect;
* ``out_of_library_unexplained_rate``: out-of-library cases answered ``unexplained``;
* ``holdout_gap_shrink_median``: gap shrink on the holdout record when the verdict is right;
* ``pair_accuracy``: two-effect cases whose verdict names both.
"""
from __future__ import annotations

import math
import random
import time
from dataclasses import replace
from typing import Callable

import numpy as np

from ..effects import EFFECT_NAMES, EFFECTS
from ..measurement import MeasurementParams, synthesize_record
from ..params import CellParams

KINDS_PATTERN = ("single",) * 6 + ("none", "pair", "out_of_library", "out_of_library")


def draw_value(name: str, rng: random.Random) -> tuple[float, ...]:
    """A realistic magnitude of effect ``name``."""
    e = EFFECTS[name]
    vals = []
    for k, (lo, hi) in enumerate(e.realistic):
        v = rng.uniform(lo, hi)
        if name in ("tool_offset", "mass_error"):
            v *= rng.choice((-1.0, 1.0))
        vals.append(v)
    return tuple(vals)


def make_case(index: int, kind: str, rng: random.Random, base: CellParams,
              measurement: MeasurementParams) -> dict:
    """Draw a case and record its three runs (redrawn until the true runs are valid)."""
    singles_cycle = EFFECT_NAMES
    for _attempt in range(20):
        if kind == "none":
            truth: tuple = ()
        elif kind == "pair":
            a, b = rng.sample(EFFECT_NAMES, 2)
            truth = ((a, draw_value(a, rng)), (b, draw_value(b, rng)))
        else:
            name = singles_cycle[(index + rng.randrange(len(singles_cycle))) % len(singles_cycle)] \
                if kind == "out_of_library" else singles_cycle[index % len(singles_cycle)]
            truth = ((name, draw_value(name, rng)),)
        cell = base
        for n, v in truth:
            cell = EFFECTS[n].apply(cell, v)
        movements = rng.sample((1, 2, 3, 4), 3)
        records, ok = [], True
        for j, mv in enumerate(movements):
            c = replace(cell, movement=replace(cell.movement, number=mv))
            try:
                rec, run = synthesize_record(c, measurement, seed=rng.randrange(2 ** 31),
                                             name=f"case{index}-m{mv}")
            except (RuntimeError, ValueError):
                ok = False
                break
            if run.F_max >= c.material.F_break:
                ok = False
                break
            records.append(rec)
        if ok:
            return {"index": index, "kind": kind, "truth": truth, "movements": movements,
                    "records": records}
    raise RuntimeError(f"case {index}: no valid {kind} case in 20 draws")


def score_case(case: dict, diag) -> dict:
    names = [n for n, _ in case["truth"]]
    verdict = diag.verdict
    named = verdict.split("+") if verdict not in ("none", "unexplained") else []
    row = {"index": case["index"], "kind": case["kind"], "movements": case["movements"],
           "truth": {n: list(v) for n, v in case["truth"]}, "verdict": verdict,
           "verdict_params": ({n: list(v) for n, v in diag.verdict_fit.values.items()}
                              if diag.verdict_fit else None),
           "J_nominal_fit": diag.J0, "J_nominal_holdout": diag.J0_holdout,
           "gap_after": diag.gap_after, "gap_before": diag.gap_before, "simulations": diag.runs}
    if case["kind"] == "single":
        row["correct"] = named == names
    elif case["kind"] == "pair":
        row["correct"] = sorted(named) == sorted(names)
    elif case["kind"] == "none":
        row["correct"] = not named
    else:
        row["correct"] = verdict == "unexplained"
    if case["kind"] in ("single", "pair") and row["correct"]:
        errs = []
        for n, v in case["truth"]:
            fit = np.asarray(diag.verdict_fit.values[n], float)
            true = np.asarray(v, float)
            errs.append(float(np.linalg.norm(fit - true) / np.linalg.norm(true)))
        row["param_rel_error"] = max(errs)
        h = diag.gap_after.get("holdout")
        row["holdout_gap_shrink"] = h.get("shrink") if h else None
    return row


def summarise(rows: list[dict], wall: float) -> dict:
    def frac(sel, key="correct"):
        sel = list(sel)
        return (sum(bool(r[key]) for r in sel) / len(sel)) if sel else None

    single = [r for r in rows if r["kind"] == "single"]
    none = [r for r in rows if r["kind"] == "none"]
    ool = [r for r in rows if r["kind"] == "out_of_library"]
    pair = [r for r in rows if r["kind"] == "pair"]
    errs = [r["param_rel_error"] for r in rows if r["kind"] == "single" and "param_rel_error" in r]
    shrink = [r["holdout_gap_shrink"] for r in rows if r.get("holdout_gap_shrink") is not None]
    per_effect = {}
    for n in EFFECT_NAMES:
        sel = [r for r in single if list(r["truth"]) == [n]]
        if sel:
            per_effect[n] = {"cases": len(sel), "correct": sum(r["correct"] for r in sel)}
    ool_verdicts: dict = {}
    for r in ool:
        ool_verdicts[r["verdict"]] = ool_verdicts.get(r["verdict"], 0) + 1
    return {
        "cases": len(rows),
        "single_cases": len(single), "none_cases": len(none), "pair_cases": len(pair),
        "out_of_library_cases": len(ool),
        "top1_accuracy": frac(single),
        "param_rel_error_median": float(np.median(errs)) if errs else None,
        "no_effect_false_name_rate": (1.0 - frac(none)) if none else None,
        "out_of_library_unexplained_rate": frac(ool),
        "holdout_gap_shrink_median": float(np.median(shrink)) if shrink else None,
        "pair_accuracy": frac(pair),
        "per_effect": per_effect,
        "out_of_library_verdicts": ool_verdicts,
        "wall_time_s": wall,
    }


def run_benchmark(n: int = 40, seed: int = 1, jobs: int | None = None,
                  progress: Callable[[dict], None] | None = None) -> dict:
    """Run ``n`` cases; returns the summary with every case under ``case_results``."""
    from .engine import diagnose
    rng = random.Random(seed)
    base = CellParams()
    measurement = MeasurementParams()
    rows = []
    t0 = time.monotonic()
    for i in range(n):
        kind = KINDS_PATTERN[i % len(KINDS_PATTERN)]
        case = make_case(i, kind, rng, base, measurement)
        library = EFFECT_NAMES
        if kind == "out_of_library":
            library = tuple(x for x in EFFECT_NAMES if x != case["truth"][0][0])
        diag = diagnose(case["records"][:2], case["records"][2:], library=library, jobs=jobs)
        row = score_case(case, diag)
        row["library_size"] = len(library)
        rows.append(row)
        if progress is not None:
            progress(row)
    out = summarise(rows, time.monotonic() - t0)
    out["seed"] = seed
    out["case_results"] = rows
    return out


def is_fraction(v) -> bool:
    return v is None or (isinstance(v, float) and 0.0 <= v <= 1.0 and not math.isnan(v))
