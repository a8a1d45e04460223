"""``rheo-shaping diagnose-benchmark``: the diagnosis scored on stand-in records with withheld effects."""
from __future__ import annotations

import argparse
import json
import sys

from . import UserError
from .common import output_path


def add_parser(sub) -> None:
    p = sub.add_parser(
        "diagnose-benchmark", help="score the diagnosis on synthetic records with withheld effects",
        description="Make stand-in records with one effect (some with two, some with none, some "
                    "outside the diagnosis's library) at realistic magnitudes across movements 1-4, "
                    "diagnose each case on two records with a third held out, without telling the "
                    "truth, and score: top-1 accuracy, parameter error, false names on no-effect "
                    "records, 'unexplained' on out-of-library effects, holdout gap shrink. "
                    "About 1-2 min per case on 2 cores (docs/diagnosis.md).")
    p.add_argument("--n", type=int, default=40, help="number of cases (default 40)")
    p.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    p.add_argument("--jobs", type=int, default=None, help="worker processes (default: all cores)")
    p.add_argument("--save", metavar="FILE", help="also write the summary with every case to FILE (JSON)")
    p.add_argument("--force", action="store_true", help="overwrite --save's file")
    p.add_argument("--json", action="store_true", help="print one JSON object (summary) instead of a table")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.n < 1:
        raise UserError(f"--n = {args.n} is invalid: expected at least 1 case")
    if args.jobs is not None and args.jobs < 1:
        raise UserError(f"--jobs = {args.jobs} is invalid: expected at least 1")
    save = output_path(args.save, args.force, "file")
    from tqdm import tqdm

    from ..diagnosis.benchmark import run_benchmark
    bar = tqdm(total=args.n, desc="diagnose-benchmark", unit="case", file=sys.stderr,
               disable=args.quiet)

    def progress(row: dict) -> None:
        bar.update(1)
        bar.set_postfix_str(f"{row['kind']} {'/'.join(row['truth']) or '-'} -> {row['verdict']}")

    out = run_benchmark(args.n, args.seed, args.jobs, progress)
    bar.close()
    if save is not None:
        save.write_text(json.dumps(out, indent=1, default=float))
    summary = {k: v for k, v in out.items() if k != "case_results"}
    if args.json:
        print(json.dumps(summary, default=float))
        return 0
    print(f"{out['cases']} cases ({out['single_cases']} single, {out['none_cases']} none, "
          f"{out['pair_cases']} pairs, {out['out_of_library_cases']} out of library), "
          f"{out['wall_time_s']:.0f} s")
    for key, target in (("top1_accuracy", ">= 0.90"), ("param_rel_error_median", ""),
                        ("no_effect_false_name_rate", "<= 0.05"),
                        ("out_of_library_unexplained_rate", ">= 0.80"),
                        ("holdout_gap_shrink_median", ">= 0.70"), ("pair_accuracy", "")):
        v = out[key]
        print(f"  {key:34s} {'n/a' if v is None else f'{v:.3f}':>8s}  {target}")
    for name, pe in out["per_effect"].items():
        print(f"  {name:16s} {pe['correct']}/{pe['cases']}")
    return 0
