"""``rheo-shaping identify``: material constants from creep and tensile tests.

``--method paper`` runs the paper's three steps (Sec. 3.4, Eq. 10, 11, 12-13);
``--method joint`` fits Maxwell, three-element and Burgers models jointly to
all the data and chooses one by BIC.  File formats: ``docs/material.md``.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from . import UserError
from ..identification.estimates import Estimate
from ..material.three_element import SPECIMEN_LENGTH_M
from ..identification.material_data import (
    CreepCurve,
    CreepResiduals,
    DataFormatError,
    TensileCurve,
    material_file_kind,
    read_creep_curve,
    read_creep_residuals,
    read_tensile_curve,
)

DEFAULT_SPEED = 1e-3
_NAMES = ("k1", "c1", "c2", "k2")
_UNITS = {"k1": "N/m", "c1": "N s/m", "c2": "N s/m", "k2": "N/m"}


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "identify", help="identify k1, c1, c2 from creep and tensile tests",
        description="Identify the material constants (on the 0.1 m specimen) from a creep "
                    "residual "
                    "table or creep curves and, optionally, tensile curves. Formats: "
                    "docs/material.md.")
    p.add_argument("--creep", metavar="FILE", action="append", required=True,
                   help="creep residual table (F_N,t1_s,x_residual_m) or creep curve "
                        "(t_s,F_N,x_m); repeatable")
    p.add_argument("--tensile", metavar="FILE", nargs="+", action="extend", default=[],
                   help="tensile curve(s) (t_s,F_N), pulled at constant speed from t = 0")
    p.add_argument("--method", choices=("paper", "joint"), default="paper",
                   help="paper: the three steps of Sec. 3.4 (default); joint: nonlinear fit of "
                        "all "
                        "data with model choice (Maxwell / three-element / Burgers)")
    p.add_argument("--speed", metavar="M_PER_S", type=float, default=None,
                   help=f"pull speed of the tensile curves [m/s] (default: the file's "
                        f"'# speed_m_per_s:' comment, else {DEFAULT_SPEED:g})")
    p.add_argument("--plot", metavar="PNG", help="write residual plots to this PNG file")
    p.add_argument("--force", action="store_true", help="overwrite an existing --plot file")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.add_argument("--noise-rel", type=float, default=0.01, metavar="FRACTION",
                   help="joint: assumed relative noise of the force (shape of the weights, "
                        "default 0.01)")
    p.add_argument("--noise-abs", type=float, default=1e-3, metavar="N",
                   help="joint: assumed absolute noise floor of the force [N] (default 1e-3)")
    p.set_defaults(func=run)


# ---------------------------------------------------------------- inputs
def _read_inputs(args) -> tuple[list[CreepResiduals], list[CreepCurve], list[TensileCurve]]:
    residuals, creep_curves, tensile = [], [], []
    try:
        for f in args.creep:
            kind = material_file_kind(f)
            if kind == "creep_residuals":
                residuals.append(read_creep_residuals(f))
            elif kind == "creep_curve":
                creep_curves.append(read_creep_curve(f))
            elif kind == "tensile_curve":
                raise UserError(
                    f"{f}: is a tensile curve (columns t_s,F_N); give it with --tensile")
            else:
                read_creep_residuals(f)      # raises, naming the missing columns
        for f in args.tensile:
            kind = material_file_kind(f)
            if kind in ("creep_residuals", "creep_curve"):
                raise UserError(f"{f}: is creep data, not a tensile curve; give it with --creep")
            tensile.append(read_tensile_curve(f, args.speed, DEFAULT_SPEED))
    except DataFormatError as exc:
        raise UserError(str(exc)) from None
    return residuals, creep_curves, tensile


def _check_args(args) -> None:
    if args.speed is not None and not (math.isfinite(args.speed) and args.speed > 0.0):
        raise UserError(f"--speed {args.speed!r}: expected a positive pull speed in m/s")
    if not (math.isfinite(args.noise_rel) and args.noise_rel >= 0.0):
        raise UserError(f"--noise-rel {args.noise_rel!r}: expected a fraction >= 0")
    if not (math.isfinite(args.noise_abs) and args.noise_abs > 0.0):
        raise UserError(f"--noise-abs {args.noise_abs!r}: expected a positive force in N")
    if args.plot:
        p = Path(args.plot)
        if p.exists() and not args.force:
            raise UserError(f"{p}: exists; not overwritten (add --force to replace it)")
        if p.exists() and p.is_dir():
            raise UserError(f"{p}: is a directory, expected a PNG file name")
        if not p.parent.exists():
            raise UserError(f"{p.parent}: no such directory for --plot")


# ---------------------------------------------------------------- output
def _fmt(x: float | None, unit_free: bool = False) -> str:
    if x is None:
        return "-"
    if math.isinf(x):
        return "inf"
    return f"{x:.4g}"


def _table(params: dict[str, Estimate]) -> list[str]:
    lines = [f"  {'':4s} {'value':>10s} {'std. err.':>10s}  {'95 % interval':<22s} unit"]
    for n in _NAMES:
        e = params[n]
        ci = "-" if e.ci95 is None else f"[{_fmt(e.ci95[0])}, {_fmt(e.ci95[1])}]"
        lines.append(f"  {n:4s} {_fmt(e.value):>10s} {_fmt(e.se):>10s}  {ci:<22s} {_UNITS[n]}")
    return lines


def _curve_info(curves) -> list[dict]:
    out = []
    for c in curves:
        out.append({"source": c.source, "speed_m_per_s": c.speed, "length_m": c.length,
                    "offset_N": c.offset, "crack_found": c.crack.found,
                    "t_crack_s": c.crack.t_crack,
                    "F_crack_N": c.crack.F_crack, "points_kept": int(c.t.size)})
    return out


def _json_doc(method: str, model: str | None, params: dict[str, Estimate], extra: dict) -> dict:
    doc: dict = {"method": method, "model": model, "length_m": SPECIMEN_LENGTH_M}
    for n in _NAMES:
        doc[n] = params[n].as_dict()["value"]
    doc["se"] = {n: params[n].as_dict()["se"] for n in _NAMES}
    doc["ci95"] = {n: params[n].as_dict()["ci95"] for n in _NAMES}
    doc["units"] = dict(_UNITS)
    doc["parameters"] = {n: params[n].as_dict() for n in _NAMES}
    doc.update(extra)
    return doc


def _run_paper(args, residuals, creep_curves, tensile) -> tuple[dict, list[str]]:
    from ..identification.paper_method import identify_paper, merge_residuals
    creep = merge_residuals(residuals) if residuals else None
    try:
        r = identify_paper(creep, tensile, creep_curves)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    params = {"k1": r.k1, "c1": r.c1, "c2": r.c2,
              "k2": Estimate(math.inf, None, None, "N/m", "no series spring in the three-element "
                                                          "model")}
    if args.plot:
        from ..identification.identification_plots import plot_paper
        plot_paper(r, args.plot, tensile)
    extra = {"b": r.b.as_dict(), "model_choice": None, "curves": _curve_info(r.curves),
             "creep_tests": len(r.creep) if r.creep is not None else 0,
             "notes": [e.note for e in (r.c2, r.c1, r.k1) if e.note], "plot": args.plot}
    lines = ["method: paper (Sec. 3.4: Eq. 10, Eq. 11, Eq. 12-13); model: "
             f"{r.model or 'not determined'}",
             f"constants on the {SPECIMEN_LENGTH_M} m specimen:"] + _table(params)
    lines += _data_lines(r.curves, extra["creep_tests"], len(creep_curves))
    lines += [f"  note: {n}" for n in extra["notes"]]
    return _json_doc("paper", r.model, params, extra), lines


def _run_joint(args, residuals, creep_curves, tensile) -> tuple[dict, list[str]]:
    from ..identification.model_choice import identify_joint
    try:
        r = identify_joint(tensile, residuals, creep_curves,
                           noise_rel=args.noise_rel, noise_abs=args.noise_abs)
    except (ValueError, RuntimeError) as exc:
        raise UserError(str(exc)) from None
    if args.plot:
        from ..identification.identification_plots import plot_joint
        plot_joint(r, args.plot, tensile)
    rows = r.table()
    extra = {"model_choice": {"rule": "BIC", "best_aic": r.best_aic, "best_bic": r.best_bic,
                              "table": rows},
             "fits": {m: {"params": {n: e.as_dict() for n, e in f.params.items()},
                          "offsets_N": [o.as_dict() for o in f.offsets],
                          "converged": f.success} for m, f in r.fits.items()},
             "curves": _curve_info(r.data.curves),
             "creep_tests": len(r.data.residuals) if r.data.residuals is not None else 0,
             "notes": r.notes, "plot": args.plot}
    lines = [f"method: joint fit; model: {r.model or 'not determined'}"
             + (f" (BIC; AIC prefers {r.best_aic})" if r.best_aic and r.best_aic != r.best_bic else
                (" (AIC and BIC agree)" if r.model else "")),
             f"constants on the {SPECIMEN_LENGTH_M} m specimen:"] + _table(r.params)
    if rows:
        lines.append("model choice:")
        lines.append(
            f"  {'model':14s} {'k':>3s} {'ln L':>11s} {'AIC':>11s} {'BIC':>11s} {'dAIC':>8s} "
            f"{'dBIC':>8s}")
        for row in rows:
            lines.append(f"  {row['model']:14s} {row['k']:3d} {row['loglik']:11.2f} "
                         f"{row['aic']:11.2f} "
                         f"{row['bic']:11.2f} {row['delta_aic']:8.2f} {row['delta_bic']:8.2f}")
    lines += _data_lines(r.data.curves, extra["creep_tests"], len(creep_curves))
    lines += [f"  note: {n}" for n in r.notes]
    return _json_doc("joint", r.model, r.params, extra), lines


def _data_lines(curves, n_creep: int, n_creep_curves: int) -> list[str]:
    lines = [
        f"data: {n_creep} creep test(s), {n_creep_curves} creep curve(s), {len(curves)} tensile "
        "curve(s)"]
    for c in curves:
        crack = (f"crack at t = {c.crack.t_crack:.1f} s, F = {c.crack.F_crack:.3f} "
                 "N" if c.crack.found
                 else "no crack found (all points kept)")
        off = "no samples at rest" if c.offset is None else f"offset {c.offset:+.4f} N"
        lines.append(f"  {c.source}: v = {c.speed:g} m/s, {off}, {crack}, {c.t.size} points kept")
    return lines


def run(args: argparse.Namespace) -> int:
    _check_args(args)
    residuals, creep_curves, tensile = _read_inputs(args)
    run_ = _run_paper if args.method == "paper" else _run_joint
    doc, lines = run_(args, residuals, creep_curves, tensile)
    if args.json:
        json.dump(doc, sys.stdout, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print("\n".join(lines))
        if args.plot:
            print(f"plot: {args.plot}")
    return 0
