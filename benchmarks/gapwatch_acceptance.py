"""The gap watch's acceptance (issue 29) on stand-ins of ``rheo-shaping record``.

Nominal runs (seeds 1..--runs): how many say WARN (should be none).  For each library effect at
mid magnitude (the middle of its realistic range, rheo_shaping/sheet/effects.py; a random sign
for tool_offset and mass_error), --effect-runs runs (seeds 1..): how many say WARN before the
end of the run, and the time from the effect becoming visible (the noise-free truth one noise
std away from the nominal model in a profile node or a force axis) to WARN.  With --diagnose K,
the first K WARN runs of each effect also run the diagnosis the node starts (the run up to WARN,
as the watch keeps it) and count a verdict naming the effect as right; --diagnose-end K the
diagnosis the node starts at the end of a run that warned (the whole run).  The floor is the
shipped one (rheo_shaping/data/gapwatch_floor.json, calibrated on other seeds) or --floor FILE.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace

import numpy as np

from rheo_shaping.diagnosis.baseline import BASELINE_MODES
from rheo_shaping_validation.gapwatch_campaign import Case, default_shared, run_case
from rheo_shaping.gapwatch.floor import ResidualFloor
from rheo_shaping.params.config import load_cell
from rheo_shaping.params.gapwatch_params import GapWatchNodeParams
from rheo_shaping.parallel import executor_from_spec, run_tasks
from rheo_shaping.sheet.effects import EFFECT_NAMES

HERE = os.path.dirname(os.path.abspath(__file__))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--params", default=os.path.join(HERE, "..", "config", "cell.yaml"))
    ap.add_argument("--runs", type=int, default=100, help="nominal runs (default 100)")
    ap.add_argument("--effect-runs", type=int, default=20, help="runs per effect (default 20)")
    ap.add_argument("--effects", default=",".join(EFFECT_NAMES))
    ap.add_argument("--diagnose", type=int, default=0, metavar="K",
                    help="diagnose the first K WARN runs of each effect (default 0)")
    ap.add_argument("--diagnose-end", type=int, default=0, metavar="K",
                    help="diagnose the whole run (the node's diagnosis at the end of a run that "
                         "warned) for the first K WARN runs of each effect (default 0)")
    ap.add_argument("--floor", default=None, help="floor file (default: the shipped one)")
    ap.add_argument("--diagnosis-baseline", default="held", choices=BASELINE_MODES,
                    help="the diagnoses' sheet knobs: held as the model cell writes them (the "
                         "node's default) or calibrated within their tolerances")
    ap.add_argument("--commissioning-error", type=float, default=0.0, metavar="U",
                    help="the true cell's sheet knobs off the model's by U(-U, U) tolerances each "
                         "(a model calibrated to within U; default 0: the model is the cell)")
    ap.add_argument("--executor", default="local:2")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    cell = load_cell(a.params)
    floor = ResidualFloor.load(a.floor)
    shared = default_shared(cell, floor, replace(GapWatchNodeParams(),
                                                 diagnosis_baseline=a.diagnosis_baseline),
                            commissioning_error=a.commissioning_error)
    effects = [e.strip() for e in a.effects.split(",") if e.strip()]
    cases = [Case("", 1 + i) for i in range(a.runs)]
    cases += [Case(e, 1 + i, diagnose=i < a.diagnose, diagnose_end=i < a.diagnose_end)
              for e in effects for i in range(a.effect_runs)]
    t0 = time.monotonic()
    done = 0

    def progress(k: int) -> None:
        """Cases finished so far, the elapsed time and an ETA, on stderr."""
        nonlocal done
        done += k
        el = time.monotonic() - t0
        left = f", ETA {el * (len(cases) - done) / done:.0f} s" if done < len(cases) else ""
        print(f"  {done}/{len(cases)} cases, {el:.0f} s{left}", file=sys.stderr, flush=True)
    with executor_from_spec(a.executor) as ex:
        res = run_tasks(ex, run_case, shared, cases, progress=progress, chunks_per_worker=16)
    wall = time.monotonic() - t0
    nominal = [r for r in res if not r["effect"]]
    out = {"runs": a.runs, "nominal_warn": sum(r["first_warn"] is not None for r in nominal),
           "nominal_error": sum(r["first_error"] is not None for r in nominal),
           "nominal_max_z": np.nanmax([r["max_z"] for r in nominal], axis=0).tolist()
           if nominal else [], "effects": {}, "wall_s": wall,
           "cpu_s_per_run": float(np.mean([r["cpu_s"] for r in res])),
           "floor": a.floor or "shipped", "diagnosis_baseline": a.diagnosis_baseline,
           "commissioning_error": a.commissioning_error}
    for e in effects:
        rs = [r for r in res if r["effect"] == e]
        warned = [r for r in rs if r["first_warn"] is not None]
        delays = [r["first_warn"] - r["visible"] for r in warned if r.get("visible") is not None]
        diag = [r["diagnosis"] for r in rs if "diagnosis" in r]
        out["effects"][e] = {
            "runs": len(rs), "warn": len(warned),
            "error": sum(r["first_error"] is not None for r in rs),
            "warn_share": len(warned) / len(rs) if rs else None,
            "visible_s_median": _med([r.get("visible") for r in rs]),
            "first_warn_s_median": _med([r["first_warn"] for r in warned]),
            "visible_to_warn_s": {"median": _med(delays), "max": max(delays) if delays else None,
                                  "min": min(delays) if delays else None},
            "diagnosed": len(diag), "right": sum(d["right"] for d in diag),
            "verdicts": [d["verdict"] for d in diag],
            "diagnosis_wall_s_median": _med([d["wall_time_s"] for d in diag])}
        end = [r["diagnosis_end"] for r in rs if "diagnosis_end" in r]
        out["effects"][e].update({
            "diagnosed_end": len(end), "right_end": sum(d["right"] for d in end),
            "verdicts_end": [d["verdict"] for d in end],
            "diagnosis_end_wall_s_median": _med([d["wall_time_s"] for d in end])})
    if a.json:
        print(json.dumps(out))
        return
    print(f"nominal: {out['nominal_warn']} WARN of {a.runs} runs (largest z window/run "
          f"profile, force: {np.round(out['nominal_max_z'], 3).tolist()})")
    print("| effect | runs | WARN | ERROR | visible at [s] | WARN at [s] | visible -> WARN [s] "
          "median (min-max) | diagnosis at WARN right | diagnosis at the end right |")
    print("|---|---|---|---|---|---|---|---|---|")
    for e, f in out["effects"].items():
        d = f["visible_to_warn_s"]
        print(f"| {e} | {f['runs']} | {f['warn']} | {f['error']} | {_f(f['visible_s_median'])} "
              f"| {_f(f['first_warn_s_median'])} | {_f(d['median'])} ({_f(d['min'])}-"
              f"{_f(d['max'])}) | {f['right']}/{f['diagnosed']} {f['verdicts']} | "
              f"{f['right_end']}/{f['diagnosed_end']} {f['verdicts_end']} |")
    print(f"wall {wall:.0f} s, gap watch CPU {out['cpu_s_per_run']:.2f} s per run")


def _med(v):
    v = [x for x in v if x is not None]
    return float(np.median(v)) if v else None


def _f(v):
    return "-" if v is None else f"{v:.1f}"


if __name__ == "__main__":
    main()
