"""``rheo-shaping-validation diagnose-benchmark``: the diagnosis scored on stand-in records
with withheld effects."""
from __future__ import annotations

import argparse
import json
import sys

from rheo_shaping.cli import UserError
from rheo_shaping.cli.common import add_executor_arguments, executor_from_args, output_path


def add_parser(sub) -> None:
    p = sub.add_parser(
        "diagnose-benchmark",
        help="score the diagnosis on synthetic records with withheld effects",
        description="Make records without the inverse crime (a true cell on a finer chain, "
                    "half steps and a softer contact than the scenario the diagnosis is told, its "
                    "written values and the measurement chain off within their tolerances) with "
                    "one effect, none, a sensor error or an effect outside the library, diagnose "
                    "each case on two records with a third held out, and score: top-1 accuracy, "
                    "false names on effect-free records, the measurement side on sensor errors, "
                    "'unexplained' on out-of-library effects, holdout gap shrink, the fitted "
                    "baseline against the truth (docs/diagnosis.md).")
    p.add_argument("--n", type=int, default=60, help="number of cases (default 60)")
    p.add_argument("--n-masses", type=int, default=31,
                   help="masses of the diagnosis's chain (the true chain has 2 N + 1; default 31)")
    p.add_argument("--process-time", type=float, default=70.0,
                   help="length of each record [s] (default 70)")
    p.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    p.add_argument("--world", default="finer-chain", metavar="NAME",
                   help="what makes the records: finer-chain (the sheet model on finer numerics, "
                        "the default) or dynamic (an independent simulator of another form: "
                        "inertia, soft contact with friction, the sheet laid and released, its "
                        "own effects and sensors; docs/diagnosis.md)")
    p.add_argument("--floor", default=None, metavar="KIND",
                   help="model-form, numerics or a calibration file (default: model-form on the "
                        "dynamic world, numerics on the finer chain)")
    p.add_argument("--initial-state", default=None, choices=("auto", "laid", "settled"),
                   help="default: auto on the dynamic world, settled on the finer chain")
    p.add_argument("--variations", default="", metavar="LIST",
                   help="the dynamic world's form variations drawn per case, each on with "
                        "probability 1/2: 'all' or names separated by commas (default none: "
                        "issue 26's world; docs/diagnosis.md, 'A family of worlds')")
    p.add_argument("--always-on", default="", metavar="LIST",
                   help="variations switched on in every case (a held-out variation)")
    add_executor_arguments(p)
    p.add_argument("--save", metavar="FILE",
                   help="also write the summary with every case to FILE (JSON); each finished "
                        "case goes to FILE.partial.jsonl as it comes, and a run with the same "
                        "arguments goes on from there")
    p.add_argument("--force", action="store_true", help="overwrite --save's file")
    p.add_argument("--json", action="store_true",
                   help="print one JSON object (summary) instead of a table")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.n < 1:
        raise UserError(f"--n = {args.n} is invalid: expected at least 1 case")
    from .benchmark import WORLDS, against_target, run_benchmark
    if args.world not in WORLDS:
        raise UserError(f"--world = {args.world!r} is unknown: expected one of "
                        f"{', '.join(WORLDS)}")
    save = output_path(args.save, args.force, "file")
    from tqdm import tqdm

    bar = tqdm(total=args.n, desc="diagnose-benchmark", unit="case", file=sys.stderr,
               disable=args.quiet)

    if args.n_masses < 3:
        raise UserError(f"--n-masses = {args.n_masses} is invalid: expected at least 3")
    if not args.process_time > 10.0:
        raise UserError(f"--process-time = {args.process_time} s is invalid: expected > 10 s")
    partial = None if save is None else str(save) + ".partial.jsonl"
    from .worlds.forms import Variation, check_variations

    def listed(text: str, option: str) -> tuple:
        names = [v.value for v in Variation] if text == "all" else \
            [x for x in text.split(",") if x]
        try:
            return check_variations(names)
        except ValueError as exc:
            raise UserError(f"{option}: {exc}") from None
    variations, always_on = listed(args.variations, "--variations"), \
        listed(args.always_on, "--always-on")
    if (variations or always_on) and args.world != "dynamic":
        raise UserError("--variations / --always-on vary the dynamic world: expected "
                        "--world dynamic")
    with executor_from_args(args) as executor:
        try:
            out = run_benchmark(args.n, args.seed, args.jobs, bar.update,
                                n_masses=args.n_masses, process_time=args.process_time,
                                executor=executor, world=args.world, floor=args.floor,
                                initial_state=args.initial_state, partial=partial,
                                variations=variations, always_on=always_on)
        except ValueError as exc:
            if partial and str(exc).startswith(partial):
                raise UserError(str(exc)) from None
            raise
    bar.close()
    if save is not None:
        save.write_text(json.dumps(out, indent=1, default=float))
    summary = {k: v for k, v in out.items() if k != "case_results"}
    if args.json:
        print(json.dumps(summary, default=float))
        return 0
    print(f"world {out['world']}: {out['cases']} cases ({out['single_cases']} single, "
          f"{out['none_cases']} none, "
          f"{out['sensor_cases']} sensor, {out['out_of_library_cases']} out of library), "
          f"{out['wall_time_s']:.0f} s")
    for r in out["undrawn_cases"]:
        print(f"  not drawn, left out: {r['no_case']}")
    for key in ("top1_accuracy", "top1_accuracy_beyond_noise", "ranked_first_right",
                "param_rel_error_median", "no_effect_false_name_rate", "no_effect_none_rate",
                "sensor_no_sheet_name_rate", "sensor_side_right_rate",
                "out_of_library_unexplained_rate", "out_of_library_cause_right",
                "holdout_gap_shrink_median", "baseline_within_tolerance_rate",
                "baseline_error_median_tolerances", "no_effect_library_name_rate",
                "out_of_library_unexplained_or_flagged_rate",
                "out_of_library_name_unflagged_rate", "interval_coverage",
                "interval_width_rel_median", "interval_coverage_bound",
                "interval_width_rel_median_bound", "diagnosis_wall_s_median",
                "diagnosis_wall_s_max"):
        v = out.get(key)
        target = against_target(out["world"], key, v)
        print(f"  {key:42s} {'n/a' if v is None else f'{v:.3f}':>8s}  {target}")
    for name, pe in out["per_effect"].items():
        print(f"  {name:16s} {pe['correct']}/{pe['cases']}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """``rheo-shaping-validation COMMAND ...`` (``python -m rheo_shaping_validation``): the
    validation's commands; a user's mistake prints one line and exits 2."""
    parser = argparse.ArgumentParser(
        prog="rheo-shaping-validation",
        description="rheo_shaping's validation: the diagnosis scored on records of stand-in "
                    "worlds (docs/diagnosis.md).")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    add_parser(sub)
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except UserError as exc:
        print(f"rheo-shaping-validation {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
