#!/usr/bin/env python3
"""Can the baseline's excess alone tell an out-of-library effect from a difference of form?
(issue 46: why the family's out-of-library effects read `none`)

Reads the rows of family benchmark runs (``diagnose-benchmark --save``'s ``.partial.jsonl``)
and prints, for the effect-free and the out-of-library cases: the quantiles of the
baseline's excess J - 1 on the fit records, per out-of-library effect; and, for a bound on
that excess moved over a range (or on the holdout's excess, or on a joint score of both
against a floor file's paired calibration cases), the share of effect-free cases within it
(`none`) beside the share of out-of-library cases beyond it.  Where no bound gives both
shares their targets (>= 0.90 and >= 0.80), no gap test on the excess can.

    python benchmarks/excess_separability.py ROWS.jsonl [ROWS.jsonl ...] \\
        [--floor benchmarks/results/issue46/floor_family_seed4601.json]
"""
from __future__ import annotations

import argparse
import json
import math

import numpy as np

BOUNDS = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0)


def rows_of(files: list[str]) -> list[dict]:
    out = []
    for fn in files:
        with open(fn) as f:
            for line in f:
                r = json.loads(line)
                r = r.get("row", r)
                if r.get("J_baseline") is not None:
                    out.append(r)
    return out


def conformal_p(score: float, cal: np.ndarray) -> float:
    """(1 + #{cal >= score}) / (n + 1)."""
    return float((1 + np.count_nonzero(cal >= score)) / (cal.size + 1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="+")
    ap.add_argument("--floor", default=None, help="a floor file with paired fit and holdout "
                    "calibration cases (the joint score's calibration), n_masses 63")
    a = ap.parse_args()
    rows = rows_of(a.files)
    ef = [r for r in rows if r["kind"] == "none"]
    ool = [r for r in rows if r["kind"] == "out_of_library"]

    def x(r: dict, holdout: bool = False) -> float:
        J = r["J_baseline_holdout"] if holdout else r["J_baseline"]
        return float(J) - 1.0 if J is not None else math.nan
    e = np.array([x(r) for r in ef])
    o = np.array([x(r) for r in ool])
    print(f"{len(rows)} rows: {len(ef)} effect-free, {len(ool)} out of library")
    q = [0.5, 0.8, 0.9, 0.95]
    print("effect-free excess J - 1 (fit), quantiles 0.5/0.8/0.9/0.95:",
          " / ".join(f"{v:.2f}" for v in np.quantile(e, q)), f"max {e.max():.2f}")
    names = sorted({n for r in ool for n in r["truth"]})
    for n in names:
        v = np.array([x(r) for r in ool if list(r["truth"]) == [n]])
        print(f"  {n:18s} {v.size:3d} cases, excess median {np.median(v):6.2f}, "
              f"below 1.0: {np.mean(v < 1.0):.2f}, below 2.4: {np.mean(v < 2.4):.2f}")
    print("\nbound on the fit excess: effect-free within (`none`) | out of library beyond")
    for b in BOUNDS:
        print(f"  {b:5.2f}: {np.mean(e <= b):.2f} | {np.mean(o > b):.2f}")
    if a.floor:
        with open(a.floor) as f:
            cfg = [c for c in json.load(f)["configs"] if c["n_masses"] == 63][0]
        cf, ch = np.asarray(cfg["fit"], float), np.asarray(cfg["holdout"], float)
        mf, mh = float(np.median(cf)), float(np.median(ch))
        scores = {"fit": lambda f, h: f, "holdout": lambda f, h: h,
                  "max(fit/median, holdout/median)": lambda f, h: max(f / mf, h / mh)}
        print(f"\nconformal tests at 0.05 against the floor's {cf.size} paired cases: "
              "effect-free beyond | out of library beyond")
        for label, s in scores.items():
            cal = np.array([s(f, h) for f, h in zip(cf, ch)])

            def beyond(sel: list[dict]) -> float:
                ok = [r for r in sel if math.isfinite(x(r, True))]
                return float(np.mean([conformal_p(s(x(r), x(r, True)), cal) <= 0.05
                                      for r in ok]))
            print(f"  {label:32s} {beyond(ef):.3f} | {beyond(ool):.3f}")


if __name__ == "__main__":
    main()
