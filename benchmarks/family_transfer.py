#!/usr/bin/env python3
"""Does the model-form floor transfer to a world variation it was not calibrated on?
(issue 46, point 2: leave one world out.)

Reads the rows of ``benchmarks/diagnosis_floor.py --variations all`` (its
``FILE.partial.jsonl``: effect-free cases, each with its drawn form) and, per variation V and
configuration (chain size, record length, grouping): the floor calibrated on the cases with
V off (its 95 % quantile of the baseline's excess J - 1, fit and holdout, as
:func:`rheo_shaping.diagnosis.floor._q95` takes it), and the share of the cases with V on
whose excess lies within it (the gap test's `none`, p > 0.05) on the fit records and on the
holdout records.  Beside it, the same share against the floor of issue 26's single world
(the stored ``rheo_shaping/data/diagnosis_floor.json``, same configuration) and against
the floor of the whole family.

    python benchmarks/family_transfer.py FILE.partial.jsonl [--json OUT]
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from rheo_shaping.diagnosis.floor import FLOOR_FILE, _q95
from rheo_shaping_validation.worlds.forms import FormParams, Variation


def on(row: dict, v: Variation) -> bool:
    return (row.get("form") or {}).get(v.value, getattr(FormParams(), v.value)) != \
        getattr(FormParams(), v.value)


def within(rows: list, q_fit: float, q_hold: float) -> float | None:
    if not rows:
        return None
    return float(np.mean([r["J_fit"] <= q_fit and r["J_holdout"] <= q_hold for r in rows]))


def stored_q(cfg: tuple) -> tuple[float, float] | None:
    n, T, nf, nh = cfg
    for c in json.loads(Path(FLOOR_FILE).read_text())["configs"]:
        if (c["n_masses"], c["process_time_s"], c["n_fit"], c["n_holdout"]) == cfg:
            return _q95(c["fit"]), _q95(c["holdout"])
    return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("partial")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    rows = [json.loads(x) for x in Path(a.partial).read_text().splitlines() if x.strip()]
    groups: dict = {}
    for r in rows:
        groups.setdefault((r["n_masses"], r["process_time_s"], r["n_fit"], r["n_holdout"]),
                          []).append(r)
    out = []
    for cfg, rs in sorted(groups.items()):
        fam = (_q95([r["J_fit"] for r in rs]), _q95([r["J_holdout"] for r in rs]))
        old = stored_q(cfg)
        print(f"N {cfg[0]} T {cfg[1]:.0f} s {cfg[2]}+{cfg[3]}: {len(rs)} cases; family floor "
              f"q95 {fam[0]:.3f}/{fam[1]:.3f}"
              + (f", issue 26's floor q95 {old[0]:.3f}/{old[1]:.3f}: family cases within it "
                 f"{within(rs, *old):.2f}" if old else ""))
        for v in Variation:
            calib = [r for r in rs if not on(r, v)]
            held = [r for r in rs if on(r, v)]
            if len(calib) < 5 or not held:
                continue
            q = (_q95([r["J_fit"] for r in calib]), _q95([r["J_holdout"] for r in calib]))
            row = {"config": list(cfg), "variation": v.value, "calibration_cases": len(calib),
                   "held_out_cases": len(held), "q95_without": list(q),
                   "held_out_none_rate": within(held, *q),
                   "held_out_none_rate_issue26_floor": within(held, *old) if old else None,
                   "held_out_J_fit_median": float(np.median([r["J_fit"] for r in held])),
                   "calibration_J_fit_median": float(np.median([r["J_fit"] for r in calib]))}
            out.append(row)
            print(f"  held out {v.value:20s} floor without it (n {len(calib):2d}) q95 "
                  f"{q[0]:.3f}/{q[1]:.3f}; held-out cases (n {len(held):2d}) within: "
                  f"{row['held_out_none_rate']:.2f}"
                  + (f" (issue 26's floor: {row['held_out_none_rate_issue26_floor']:.2f})"
                     if old else "")
                  + f"; J - 1 median held out {row['held_out_J_fit_median']:.3f}, "
                    f"calibration {row['calibration_J_fit_median']:.3f}")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
