"""Calibrate the diagnosis's gap test: the baseline's excess misfit on effect-free records.

Runs effect-free cases of ``diagnose-benchmark`` (their own seed, 99, never the scored
benchmark's) and prints the mean, standard deviation and count of J - 1 of the calibrated
baseline on the fit and the holdout records: the values of ``stats.NULL_FIT`` and
``stats.NULL_HOLD``.  Usage: ``python benchmarks/diagnosis_null.py [N_CASES] [OUT.json]``.
"""
from __future__ import annotations

import json
import sys

import numpy as np

from rheo_shaping_validation.benchmark import run_benchmark


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 12
    out = run_benchmark(n, seed=99, jobs=2, kinds=("none",))
    if len(sys.argv) > 2:
        with open(sys.argv[2], "w") as fh:
            json.dump(out, fh, indent=1, default=float)
    rows = out["case_results"]
    for key, col in (("NULL_FIT", "J_baseline"), ("NULL_HOLD", "J_baseline_holdout")):
        x = np.array([r[col] - 1.0 for r in rows])
        print(f"{key} = ({x.mean():.4f}, {x.std(ddof=1):.4f}, {x.size})")
    print(f"wall time {out['wall_time_s']:.0f} s for {n} cases")


if __name__ == "__main__":
    main()
