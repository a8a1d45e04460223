"""``rheo-shaping diagnose``: where the model parts from recorded runs, which effect causes it,
how far the gap shrinks."""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import Any
from dataclasses import replace

from ..diagnosis.options import DEFAULTS, BaselineMode, InitialMode
from ..sheet.effects import EFFECT_NAMES
from ..records.bag import RecordError, read_record
from . import UserError
from .common import add_executor_arguments, executor_from_args, output_dir, output_path


def add_parser(sub) -> None:
    p = sub.add_parser(
        "diagnose", help="diagnose the sim-to-real gap of recorded runs",
        description="Compare recorded runs (record directories: rosbag2 MCAP + scenario.yaml, "
                    "docs/records.md) with their model: first a baseline calibrated within what a "
                    "careful user knows (material, mass, bonds, sag, cake, vision and load cell), "
                    "then which side of the sensors, then which unmodelled effect explains what "
                    "the baseline cannot (every effect of the library fitted to RECORD..., "
                    "checked on --holdout, with its p-value), else 'unexplained' with the "
                    "residual's signature; and how far the gap shrinks. "
                    "Method: docs/diagnosis.md.")
    p.add_argument("records", nargs="+", metavar="RECORD", help="record directories to fit")
    p.add_argument("--holdout", nargs="+", default=[],
                   metavar="RECORD", help="record directories held out")
    p.add_argument("--effects", metavar="NAMES",
                   help="comma-separated candidate effects (default: all: "
                   + ", ".join(EFFECT_NAMES) + ")")
    p.add_argument("--out", metavar="DIR", help="write report.md and PNG figures to DIR")
    p.add_argument("--force", action="store_true", help="write into an existing --out directory")
    p.add_argument("--write-scenario", metavar="FILE",
                   help="write the calibrated baseline plus the verdict's effect as a params file "
                        "(accepted by simulate, reproduce --params and the planner); the report "
                        "then shows F_max, SF, Delta and d_opt against the nominal cell")
    p.add_argument("--initial-state", default=DEFAULTS.initial_state.value,
                   choices=[m.value for m in InitialMode],
                   help="how each record's model starts: laid (the first profile frame's sheet, "
                        "released then), settled (the scenario's drape settled before t = 0) or "
                        "auto (laid when the records show the sheet moving before the tool "
                        "touches; the default)")
    p.add_argument("--floor", default=str(DEFAULTS.floor), metavar="KIND",
                   help="what a gap is judged against: model-form (the default: what the "
                        "baseline leaves on effect-free records of a simulator of another form, "
                        "calibrated per configuration), numerics (the model's own finer chain: "
                        "numerics only) or a calibration file (benchmarks/diagnosis_floor.py)")
    p.add_argument("--reference", nargs="+", default=[], metavar="RECORD",
                   help="effect-free records of this cell (a commissioning run, at least two): "
                        "the floor is scaled to what the baseline leaves on them")
    p.add_argument("--tolerance", nargs=2, type=float, metavar=("PROFILE_MM", "FORCE_N"),
                   help="practical tolerance: a baseline remainder below both (systematic "
                        "profile RMS [mm], tool-force RMS [N]) is not worth naming")
    p.add_argument("--baseline", default=DEFAULTS.baseline.value,
                   choices=[m.value for m in BaselineMode],
                   help="the sheet knobs (material, mass, bonds, sag, cake) fitted within their "
                        "tolerances (calibrated, the default), or held as the scenario writes "
                        "them (held: the scenario is a cell already calibrated, for one by "
                        "--write-scenario of a commissioning run; what changed since)")
    add_executor_arguments(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


class _Progress:
    """The diagnosis's progress as "stage k of n", a tqdm bar per stage on stderr.

    A stage's total is known when it begins (the engine says it: one batch, or the most
    its batches can run), so its ETA holds; only the candidate checks, whose later
    batches depend on the earlier results, learn their total batch by batch (their bar
    says so). A stage that ends short of its most closes at what it ran."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.bar: Any = None          # a tqdm bar (the current stage's)
        self.fixed = False

    def stage(self, k: int, n: int, name: str, total: int | None) -> None:
        from tqdm import tqdm
        self.close()
        grows = total is None
        desc = f"diagnose: stage {k} of {n}, {name}" + (" (total grows)" if grows else "")
        self.bar = tqdm(desc=desc, unit="sim", file=sys.stderr, disable=self.quiet,
                        total=0 if grows else total)
        self.fixed = not grows

    def expect(self, n: int) -> None:
        if self.bar is None:
            self.stage(1, 1, "simulations", None)
        if not self.fixed:
            self.bar.total += n
        elif self.bar.n + n > self.bar.total:       # more than the engine said: never less
            self.bar.total = self.bar.n + n
        self.bar.refresh()

    def __call__(self, n: int) -> None:
        self.bar.update(n)

    def close(self) -> None:
        if self.bar is not None:
            if self.bar.total != self.bar.n:
                self.bar.total = self.bar.n
                self.bar.refresh()
            self.bar.close()
            self.bar = None


def _num(v: float | None, scale: float, digits: int) -> str:
    """``v * scale`` to ``digits`` decimals, "n/a" when it is missing or not finite."""
    return "n/a" if v is None or not math.isfinite(v) else f"{v * scale:.{digits}f}"


def run(args: argparse.Namespace) -> int:
    library = EFFECT_NAMES
    if args.effects:
        library = tuple(x.strip() for x in args.effects.split(",") if x.strip())
        bad = [x for x in library if x not in EFFECT_NAMES]
        if bad or not library:
            raise UserError(f"--effects: unknown effect '{bad[0] if bad else args.effects}': "
                            "expected some of " + ", ".join(EFFECT_NAMES))
    scen = output_path(args.write_scenario, args.force, "--write-scenario file")
    out = output_dir(args.out, args.force)
    tol = None
    if args.tolerance is not None:
        if not all(v >= 0 for v in args.tolerance):
            raise UserError(f"--tolerance {args.tolerance[0]} {args.tolerance[1]}: expected two "
                            "numbers >= 0 (profile [mm], tool force [N])")
        tol = (args.tolerance[0] * 1e-3, args.tolerance[1])
    try:
        fit = [read_record(p) for p in args.records]
        hold = [read_record(p) for p in args.holdout]
        ref = [read_record(p) for p in args.reference]
    except RecordError as exc:
        raise UserError(str(exc)) from None
    from ..diagnosis.engine import diagnose
    progress = _Progress(args.quiet)
    t0 = time.monotonic()
    try:
        with executor_from_args(args) as executor:
            diag = diagnose(fit, hold, library=library, progress=progress,
                            executor=executor, initial_state=args.initial_state,
                            floor=args.floor, reference=ref, tolerance=tol,
                            baseline=args.baseline)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    finally:
        progress.close()
    result = diag.to_json()
    result["wall_time_s"] = time.monotonic() - t0
    process = None
    if scen is not None:
        corrected = diag.corrected
        assert corrected is not None            # the engine always gives the corrected cell
        from ..params.config import dump_cell
        from ..diagnosis.result import process_figures
        scen.write_text("# rheo-shaping diagnose: calibrated baseline + verdict "
                        f"'{diag.verdict_name}' of {', '.join(diag.records)}\n"
                        + dump_cell(corrected))
        nominal = fit[0].scenario
        process = process_figures(replace(nominal, movement=replace(nominal.movement, number=4)),
                                  replace(corrected,
                                          movement=replace(corrected.movement, number=4)))
        result["scenario"] = str(scen)
        result["process"] = process
    if out is not None:
        from ..diagnosis.report import write
        result["report"] = [str(p) for p in write(diag, out, process)]
    if args.json:
        print(json.dumps(result, default=float))
        return 0
    print(f"verdict: {diag.verdict_name}")
    if diag.verdict_fit:
        for n, v in diag.verdict_fit.values.items():
            iv = diag.verdict_fit.interval[n]
            print(f"  {n} = "
                  + ", ".join(f"{x:.4g} [{lo:.4g}, {hi:.4g}]" for x, (lo, hi) in zip(v, iv)))
        print(f"  p = {diag.verdict_fit.p:.3g}")
    fl = diag.floor
    if fl.model_form:
        b = fl.baseline
        print(f"floor ({fl.source}): 95 % bound J - 1 = {fl.q95_fit:.4f}; the baseline "
              f"leaves {b.J_minus_1:.4f} ({_num(b.noise_units, 1, 2)} noise units, profile "
              f"{_num(b.profile_systematic_m, 1e3, 3)} mm, tool force "
              f"{_num(b.force_systematic_N, 1e3, 2)} mN)"
              + (": below the practical tolerance" if fl.below_tolerance else ""))
        if fl.verdict is not None:
            v = fl.verdict
            print(f"  the verdict leaves {v.J_minus_1:.4f} ({_num(v.noise_units, 1, 2)} noise "
                  f"units, profile {_num(v.profile_systematic_m, 1e3, 3)} mm, tool force "
                  f"{_num(v.force_systematic_N, 1e3, 2)} mN): "
                  + ("beyond the floor" if v.beyond_floor else "within the floor"))
    print(f"gap test: baseline J - 1 = {diag.J_base - 1:.4f}, p_gap = {diag.p_gap:.3g}; "
          f"{diag.baseline_took_text()}; "
          f"side: {diag.side['side']}")
    if diag.signature:
        print("signature: kinds of cause " + ", ".join(
            f"{c['kind']} {c['score']:.2f}" for c in diag.signature["causes"][:3]))
    print("where (calibrated baseline; systematic RMS in units of the noise):")
    for w in diag.where[:5]:
        print(f"  {w['rank']}. {w['kind']} {w['name']}: {w['relative']:.2f}")
    for grp in ("fit", "holdout"):
        before, after = diag.gap_before.group(grp), diag.gap_after.group(grp)
        if before is not None and after is not None:
            print(f"gap on {grp} records: profile RMS {before.profile_rms_m * 1e3:.3f} -> "
                  f"{after.profile_rms_m * 1e3:.3f} mm, "
                  f"gap beyond noise {before.gap:.3f} -> {after.gap:.3f}")
    print(f"{diag.runs} simulations, {result['wall_time_s']:.0f} s"
          + (f"; report in {out}" if out else ""))
    return 0
