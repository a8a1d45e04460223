#!/usr/bin/env python3
"""Convergence study of the sheet model on the default cell, movements 1-4.

For each movement the default cell (``CellParams()``, read fresh at run time)
is run with ``run_scenario`` at

* the default solver settings,
* the time steps halved (``solver.dt``, ``solver.dt_still`` and
  ``solver.max_tool_step`` all halved), and halved once more,
* the number of masses doubled (``sheet.n_masses`` N -> 2N -> 4N; 24 -> 48 -> 96
  by default),

and F_max [N] (``RunResult.F_max``, the largest link tension) and Delta [m]
(``RunResult.delta``) are compared between each run and the one it refines.
The criterion (docs/model.md): F_max changes by < 1 % and Delta by < 0.1 mm
when the time step is halved or N doubled.

The runs go to a process pool over the machine's cores (``--jobs``) with a
progress bar on stderr.  ``--json`` prints one JSON object.  ``--levels 3``
adds a third refinement (dt/8, 8N); ``--settle`` also halves
``solver.dt_settle`` (the inertial pre-sag) with the process steps.  The
tool's largest force on the sheet is printed too: if the tool hardly touches
the sheet, F_max is the sag tension and says little about the tool's effect.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")        # one thread per worker process

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import multiprocessing  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor, as_completed  # noqa: E402
from dataclasses import asdict, replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

try:
    import rheo_shaping  # noqa: F401
except ImportError:                                   # run from a source tree without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rheo_shaping.params.cell import CellParams  # noqa: E402
from rheo_shaping.planning.movement import movement_plan  # noqa: E402
from rheo_shaping.sheet.simulation import run_scenario  # noqa: E402

F_TOL = 0.01        # relative change of F_max
DELTA_TOL = 1e-4    # m, change of Delta


def cell_fingerprint() -> str:
    """Short hash of the default cell as this process reads it (params.py is being edited)."""
    import hashlib
    return hashlib.sha1(repr(asdict(CellParams())).encode()).hexdigest()[:12]


def variant(kind: str, level: int, settle: bool = False) -> CellParams:
    """The default cell with its time steps divided by 2**level (kind "dt") or N
    multiplied by 2**level (kind "N")."""
    p = CellParams()
    if level == 0:
        return p
    f = 2 ** level
    if kind == "dt":
        sp = p.solver
        sp = replace(sp, dt=sp.dt / f, dt_still=sp.dt_still / f,
                     max_tool_step=sp.max_tool_step / f,
                     **({"dt_settle": sp.dt_settle / f} if settle else {}))
        return replace(p, solver=sp)
    if kind == "N":
        return replace(p, sheet=replace(p.sheet, n_masses=p.sheet.n_masses * f))
    raise ValueError(kind)


def run_one(movement: int, kind: str, level: int, settle: bool) -> dict:
    p = variant(kind, level, settle)
    path = movement_plan(p, movement)
    t0 = time.perf_counter()
    r = run_scenario(p, path)
    wall = time.perf_counter() - t0
    tool_force = np.hypot(r.tool_force[:, 0], r.tool_force[:, 1])
    touching = np.any(np.hypot(r.tool_contact[..., 0], r.tool_contact[..., 1]) > 0.0, axis=1)
    return {"movement": movement, "kind": kind, "level": level,
            "n_masses": p.sheet.n_masses, "dt_s": p.solver.dt, "dt_still_s": p.solver.dt_still,
            "max_tool_step_m": p.solver.max_tool_step, "dt_settle_s": p.solver.dt_settle,
            "F_max_N": r.F_max, "F_max_link": r.peak.link, "F_max_time_s": r.peak.time,
            "delta_m": r.delta, "SF": r.SF, "steps": int(r.t.size - 1), "wall_s": wall,
            "tool_force_max_N": float(tool_force.max()), "tool_contact_steps": int(touching.sum()),
            "cell_fingerprint": cell_fingerprint()}


def label(kind: str, level: int) -> str:
    if level == 0:
        return "default"
    return f"dt/{2 ** level}" if kind == "dt" else f"N x{2 ** level}"


def compare(runs: dict, movements, levels: int) -> list[dict]:
    rows = []
    for mv in movements:
        for kind in ("dt", "N"):
            for lv in range(1, levels + 1):
                a = runs[(mv, kind, lv - 1)]         # (mv, "N", 0) is the default run too
                b = runs[(mv, kind, lv)]
                fa, fb = a["F_max_N"], b["F_max_N"]
                rel = (fb - fa) / fa if fa > 0 else (0.0 if fb == fa else math.inf)
                da, db = a["delta_m"], b["delta_m"]
                dd = (db - da) if (math.isfinite(da) and math.isfinite(db)
                                   ) else (0.0 if da == db else math.inf)
                rows.append({"movement": mv, "refinement": f"{label(kind, lv - 1)} -> "
                                                           f"{label(kind, lv)}",
                             "kind": "time step halved" if kind == "dt" else "N doubled",
                             "F_max_from_N": fa, "F_max_to_N": fb, "F_max_rel_change": rel,
                             "delta_from_m": da, "delta_to_m": db, "delta_change_m": dd,
                             "F_ok": abs(rel) < F_TOL, "delta_ok": abs(dd) < DELTA_TOL,
                             "ok": abs(rel) < F_TOL and abs(dd) < DELTA_TOL})
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("--movements", type=int, nargs="+",
                    default=[1, 2, 3, 4], help="paper movements (default 1 2 3 4)")
    ap.add_argument("--levels", type=int, default=2,
                    help="refinements of each kind (default 2: dt/2, dt/4; 2N, 4N)")
    ap.add_argument("--settle", action="store_true",
                    help="also halve solver.dt_settle with the process steps")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                    help="worker processes (default: all cores)")
    ap.add_argument("--json", action="store_true",
                    help="print one JSON object instead of the tables")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)

    p0 = CellParams()
    jobs = [(mv, "dt", 0) for mv in args.movements]
    jobs += [(mv, kind, lv) for mv in args.movements for kind in ("dt", "N")
             for lv in range(1, args.levels + 1)]
    # biggest first: N x 2**levels costs the most
    cost = lambda j: (2 ** j[2]) ** (1.5 if j[1] == "N" else 1.0)  # noqa: E731
    jobs.sort(key=lambda j: -cost(j))
    try:
        from tqdm import tqdm
        bar = tqdm(total=len(jobs), desc="convergence runs",
                   file=sys.stderr, disable=args.no_progress)
    except ImportError:                                # pragma: no cover
        bar = None
    runs: dict = {}
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.jobs,
                             mp_context=multiprocessing.get_context("spawn")) as ex:
        futs = {ex.submit(run_one, mv, kind, lv, args.settle): (mv, kind, lv)
                for mv, kind, lv in jobs}
        for fu in as_completed(futs):
            runs[futs[fu]] = fu.result()
            if bar is not None:
                bar.update(1)
    if bar is not None:
        bar.close()
    wall = time.perf_counter() - t0
    for mv in args.movements:                            # the default run is level 0 of both kinds
        runs[(mv, "N", 0)] = runs[(mv, "dt", 0)]
    rows = compare(runs, args.movements, args.levels)
    out = {"cell_defaults": {"n_masses": p0.sheet.n_masses, "solver": asdict(p0.solver),
                             "process_time_s": p0.movement.process_time},
           "criterion": {"F_max_rel_change_lt": F_TOL, "delta_change_lt_m": DELTA_TOL},
           "settle_halved_too": args.settle,
           "runs": [runs[k] for k in sorted(runs) if not (k[1] == "N" and k[2] == 0)],
           "comparisons": rows, "all_ok": all(r["ok"] for r in rows),
           "wall_s": wall, "jobs": args.jobs, "cell_fingerprint": cell_fingerprint()}
    prints = {r["cell_fingerprint"] for r in runs.values()}
    if len(prints) > 1:
        out["warning"] = ("the default cell changed during the study (params.py edited): "
                          f"{sorted(prints)}")
    if args.json:
        print(json.dumps(out, default=float))
        return 0
    sp = p0.solver
    print(f"default cell: N = {p0.sheet.n_masses}, dt {sp.dt:g} s, dt_still {sp.dt_still:g} s, "
          f"max_tool_step {1e3 * sp.max_tool_step:g} mm, settle {sp.settle_time:g} s at dt_settle "
          f"{sp.dt_settle:g} s{' (halved with the steps)' if args.settle else ' (kept)'}; "
          f"{p0.movement.process_time:g} s process; cell fingerprint {out['cell_fingerprint']}")
    print(f"\n{'mv':>2} {'run':>8} {'N':>4} {'dt [s]':>7} {'steps':>5} {'F_max [N]':>10} "
          f"{'link':>4} "
          f"{'t_Fmax [s]':>10} {'Delta [mm]':>10} {'tool F max [N]':>14} {'tool steps':>10} "
          f"{'wall [s]':>8}")
    for mv in args.movements:
        for kind, lv in [("dt",
                          0)] + [(k, lv) for k in ("dt", "N") for lv in range(1, args.levels + 1)]:
            r = runs[(mv, kind, lv)]
            print(f"{mv:>2} {label(kind, lv):>8} {r['n_masses']:>4} {r['dt_s']:7.4g} "
                  f"{r['steps']:>5} "
                  f"{r['F_max_N']:10.6f} {r['F_max_link']:>4} {r['F_max_time_s']:10.2f} "
                  f"{1e3 * r['delta_m']:10.4f} {r['tool_force_max_N']:14.4g} "
                  f"{r['tool_contact_steps']:>10} "
                  f"{r['wall_s']:8.2f}")
    print(
        f"\ncriterion: |F_max change| < {100 * F_TOL:g} % and |Delta change| < "
        f"{1e3 * DELTA_TOL:g} mm")
    print(f"{'mv':>2} {'refinement':>20} {'F_max change':>13} {'Delta change [mm]':>17}  result")
    for r in rows:
        verdict = "ok" if r["ok"] else "FAILS (" + ", ".join(
            x for x, good in (("F_max", r["F_ok"]), ("Delta", r["delta_ok"])) if not good) + ")"
        print(f"{r['movement']:>2} {r['refinement']:>20} {100 * r['F_max_rel_change']:12.4f}% "
              f"{1e3 * r['delta_change_m']:17.5f}  {verdict}")
    if out.get("warning"):
        print(f"\nWARNING: {out['warning']}; rerun")
    print(f"\nall refinements meet the criterion: {'yes' if out['all_ok'] else 'NO'} "
          f"({len(jobs)} runs, {wall:.1f} s wall on {args.jobs} processes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
