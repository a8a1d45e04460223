"""The figures of a (partial) diagnose-benchmark run, with the named effects' intervals beside
the worst-case bound on the same cases.

    python benchmarks/interval_summary.py RUN.json.partial.jsonl [--out SUMMARY.json]

Reads the finished cases of ``RUN.json.partial.jsonl`` (``diagnose-benchmark --save``),
summarises them as the command does (``rheo_shaping_validation.benchmark.score.summarise``)
and prints the acceptance figures with their case counts, then per right name: the truth
inside the interval estimated from the remainder and inside the worst-case bound, and both
widths relative to the value (docs/diagnosis.md, *The model-form part of an interval*).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from rheo_shaping_validation.benchmark.score import summarise

KEYS = ("no_effect_none_rate", "no_effect_library_name_rate", "top1_accuracy_beyond_noise",
        "top1_accuracy", "out_of_library_unexplained_or_flagged_rate",
        "out_of_library_unexplained_flagged_or_chain_rate",
        "out_of_library_name_unflagged_rate", "sensor_no_sheet_name_rate",
        "holdout_gap_shrink_median", "interval_coverage", "interval_width_rel_median",
        "interval_coverage_bound", "interval_width_rel_median_bound",
        "diagnosis_wall_s_median", "diagnosis_wall_s_max", "simulations_median")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("partial")
    ap.add_argument("--out")
    a = ap.parse_args()
    rows = [json.loads(ln)["row"] for ln in Path(a.partial).read_text().splitlines()
            if ln.strip()]
    rows = [r for r in rows if "no_case" not in r]
    s = summarise(rows, float("nan"))
    print(f"{s['cases']} cases: {s['single_cases']} single ({s['single_beyond_noise_cases']} "
          f"beyond the floor), {s['none_cases']} none, {s['sensor_cases']} sensor, "
          f"{s['out_of_library_cases']} out of library")
    for k in KEYS:
        v = s.get(k)
        print(f"  {k:44s} {'n/a' if v is None else f'{v:.3f}'}")
    named = [r for r in rows if r.get("in_interval") is not None]
    print(f"right names with an interval: {len(named)}")
    for r in sorted(named, key=lambda r: list(r["truth"])[0]):
        n = list(r["truth"])[0]
        print(f"  case {r['index']:3d} {n:15s} true {r['truth'][n]} fitted "
              f"{r['verdict_params'][n]}  in: {r['in_interval']} "
              f"width {r['interval_width_rel']:.3f} | bound in: {r.get('in_interval_bound')} "
              f"width {r.get('interval_width_rel_bound', float('nan')):.3f}")
    both = [r for r in named if r.get("in_interval_bound") is not None]
    if both:
        print(f"same {len(both)} cases: remainder {sum(r['in_interval'] for r in both)} in, "
              f"median width {np.median([r['interval_width_rel'] for r in both]):.3f}; "
              f"bound {sum(r['in_interval_bound'] for r in both)} in, median width "
              f"{np.median([r['interval_width_rel_bound'] for r in both]):.3f}")
    if a.out:
        s["case_results"] = rows
        Path(a.out).write_text(json.dumps(s, indent=1, default=float))


if __name__ == "__main__":
    main()
