#!/usr/bin/env python3
"""Closed-loop campaign (issue 43): is re-planning from the online estimate worth it?

Cells are drawn around the default cell: k1 and c2 each x uniform [0.7, 1.3], mass per
length x uniform [0.8, 1.2], mould and tool friction uniform [0, 0.3], movement 1-4
(uniform), the params file's speed 1x or 2x the paper's 1 mm/s.  The planner knows only
the params file (the default material, no friction, the drawn movement and speed).  Each
cell is run offline in the core (``rheo_shaping.adaptive.loop.run_closed_loop``: the true
cell is the simulator node's core ``SetpointRun``, the monitor aborts at its threshold)
once with the fixed plan and once adaptive, and its offline optimum is computed knowing
the true cell (``adaptive.optimum``).  With ``--world N`` the first N draws are also run
against the dynamic world (``adaptive.world_loop``: another model form), fixed and
adaptive.

Reported per arm: shaped (no abort, no tear, Delta <= 5 mm), aborts, tears, cycle time
against the optimum (median ratio over the cells both shaped), the CPU cost of a refresh
(estimate + re-plan).  Progress with an ETA on stderr.

    .venv-core/bin/python benchmarks/closed_loop_campaign.py [--cells 40] [--seed 43]
        [--world 6] [--jobs 1] [--json] [--save FILE.json] [--plot FILE.png]

``--jobs N`` runs N cases at once (worker processes).  With ``--save`` every case is
written as it ends; a campaign started again with the same file, seed and ``--world``
goes on where it stopped (its cases are not run again).  The draws are those of
``closed_loop_nodes.py`` with the same seed.

Not through the ROS nodes: the node integration is not part of this core.
"""
from __future__ import annotations

import argparse
import concurrent.futures
import json
import math
import resource
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import cpu_name  # noqa: E402

from rheo_shaping.adaptive.settle import material_cell  # noqa: E402
from rheo_shaping.adaptive.loop import (LoopConfig, LoopResult, replan_limits,  # noqa: E402
                                        run_closed_loop)
from rheo_shaping.adaptive.optimum import offline_optimum  # noqa: E402
from rheo_shaping.adaptive.replan import ReplanStatus  # noqa: E402
from rheo_shaping.jsonable import json_safe  # noqa: E402
from rheo_shaping.params.cell import CellParams  # noqa: E402

NOMINAL = np.array([95.0, 1300.0, 0.3125])


def draw(rng: np.random.Generator) -> dict:
    """One cell of the campaign (factors, frictions, movement, speed factor)."""
    return {"k1": float(rng.uniform(0.7, 1.3)), "c2": float(rng.uniform(0.7, 1.3)),
            "mass": float(rng.uniform(0.8, 1.2)),
            "friction_mould": float(rng.uniform(0.0, 0.3)),
            "friction_tool": float(rng.uniform(0.0, 0.3)),
            "movement": int(rng.integers(1, 5)), "speed_factor": float(rng.choice([1.0, 2.0]))}


def cells(d: dict) -> tuple[CellParams, CellParams]:
    """(the params file's cell, the true cell) of draw ``d``."""
    base = CellParams()
    cell = replace(base, movement=replace(base.movement, number=d["movement"],
                                          speed=1e-3 * d["speed_factor"]))
    true = material_cell(cell, NOMINAL * [d["k1"], d["c2"], d["mass"]])
    true = replace(true, effects=replace(true.effects, friction_mould=d["friction_mould"],
                                         friction_tool=d["friction_tool"]))
    return cell, true


def summary(r: LoopResult) -> dict:
    costs = r.costs() if r.events else np.zeros(0)
    changes = [e.t for e in r.events if e.replan is not None and e.replan.changed]
    last = r.events[-1].estimate if r.events else None
    return {"shaped": r.shaped, "aborted": r.aborted, "torn": r.torn, "F_max": r.F_max,
            "delta": r.delta, "cycle_time": r.cycle_time, "F_abort": r.F_abort,
            "replans": len(changes), "replan_times": changes,
            "cost_max_s": float(costs.max()) if costs.size else 0.0,
            "cost_mean_s": float(costs.mean()) if costs.size else 0.0,
            "costs_s": costs.tolist(),
            "estimate": last.as_dict() if last is not None else None,
            "choice": None if r.choice is None else [r.choice.speed, r.choice.dwell_factor]}


def run_case(d: dict, world: bool) -> dict:
    cell, true = cells(d)
    config = LoopConfig(seed=d["seed"])
    out: dict = {"draw": d}
    opt = offline_optimum(true, cell, replan_limits(cell, config.detect_time, config.noise_sigma))
    ok = opt.status in (ReplanStatus.REPLANNED, ReplanStatus.KEPT)
    out["optimum"] = {"status": opt.status.value,
                      "cycle_time": opt.schedule.cycle_time if ok else math.nan,
                      "choice": [opt.schedule.choice.speed, opt.schedule.choice.dwell_factor]}
    for name, adaptive in (("fixed", False), ("adaptive", True)):
        out[name] = summary(run_closed_loop(true, cell, replace(config, adaptive=adaptive)))
    if world:
        from rheo_shaping_validation.world_loop import run_world_loop
        for name, adaptive in (("world_fixed", False), ("world_adaptive", True)):
            out[name] = summary(run_world_loop(true, cell, replace(config, adaptive=adaptive)))
    return out


def rates(results: list[dict], arm: str) -> dict:
    rows = [r[arm] for r in results if arm in r]
    if not rows:
        return {}
    ratio = [r[arm]["cycle_time"] / r["optimum"]["cycle_time"] for r in results
             if arm in r and r[arm]["shaped"] and math.isfinite(r["optimum"]["cycle_time"])]
    costs = np.concatenate([np.asarray(x["costs_s"]) for x in rows] + [np.zeros(0)])
    return {"cells": len(rows), "shaped": sum(x["shaped"] for x in rows),
            "shaped_rate": sum(x["shaped"] for x in rows) / len(rows),
            "aborted": sum(x["aborted"] for x in rows), "torn": sum(x["torn"] for x in rows),
            "gap_over_5mm": sum((not x["aborted"]) and x["delta"] > 5e-3 for x in rows),
            "cycle_over_optimum_median": float(np.median(ratio)) if ratio else math.nan,
            "cycle_time_median_s": float(np.median([x["cycle_time"] for x in rows
                                                    if x["shaped"]] or [math.nan])),
            "refresh_cost_max_s": float(costs.max()) if costs.size else 0.0,
            "refresh_cost_p95_s": float(np.percentile(costs, 95)) if costs.size else 0.0,
            "refresh_cost_mean_s": float(costs.mean()) if costs.size else 0.0}


def _cpu_s() -> float:
    """CPU time [s] of this process and its ended worker processes (user + system)."""
    me, kids = (resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cells", type=int, default=40)
    ap.add_argument("--seed", type=int, default=43)
    ap.add_argument("--world", type=int, default=0, help="first N draws also on the world")
    ap.add_argument("--jobs", type=int, default=1, help="cases run at once (worker processes)")
    ap.add_argument("--json", action="store_true", help="print the summary as JSON")
    ap.add_argument("--save", metavar="FILE", help="write every case and the summary")
    ap.add_argument("--plot", metavar="FILE", help="the campaign's figure (PNG)")
    args = ap.parse_args(argv)
    if args.jobs < 1:
        ap.error(f"--jobs {args.jobs}: expected a whole number >= 1")
    rng = np.random.default_rng(args.seed)
    draws = [dict(draw(rng), seed=args.seed * 1000 + i) for i in range(args.cells)]
    done_cases: dict[int, dict] = {}
    if args.save and Path(args.save).exists():
        old = json.loads(Path(args.save).read_text())
        for r in old.get("cases", []):
            i = int(r.get("draw", {}).get("seed", -1)) - args.seed * 1000
            if not 0 <= i < len(draws) or \
                    r["draw"] != json.loads(json.dumps(json_safe(draws[i]))):
                ap.error(f"--save {args.save}: a case of another campaign (seed, cells); "
                         "give another file to start a new one")
            if ("world_adaptive" in r) == (i < args.world):
                done_cases[i] = r          # the same case with the same arms: kept
    results: dict[int, dict] = dict(done_cases)
    todo = [i for i in range(len(draws)) if i not in results]
    wall0 = time.perf_counter()
    cpu0 = _cpu_s()

    def note(i: int, n: int) -> None:
        done = time.perf_counter() - wall0
        eta = done / n * (len(todo) - n)
        d, r = draws[i], results[i]
        if args.save:                          # every case as it ends (a partial campaign)
            ordered = [results[k] for k in sorted(results) if k < len(draws)]
            Path(args.save).write_text(json.dumps(json_safe({"cases": ordered}), indent=1))
        print(f"[{len(results)}/{len(draws)}] mv {d['movement']} x{d['speed_factor']:g} k1 "
              f"x{d['k1']:.2f} c2 x{d['c2']:.2f} m x{d['mass']:.2f}: fixed "
              f"{'shaped' if r['fixed']['shaped'] else 'NOT'} {r['fixed']['cycle_time']:.0f} s, "
              f"adaptive {'shaped' if r['adaptive']['shaped'] else 'NOT'} "
              f"{r['adaptive']['cycle_time']:.0f} s, optimum {r['optimum']['cycle_time']:.0f} s"
              f" | {done:.0f} s, ETA {eta:.0f} s", file=sys.stderr, flush=True)
    if args.jobs == 1:
        for n, i in enumerate(todo, 1):
            results[i] = run_case(draws[i], i < args.world)
            note(i, n)
    else:
        with concurrent.futures.ProcessPoolExecutor(args.jobs) as pool:
            futures = {pool.submit(run_case, draws[i], i < args.world): i for i in todo}
            for n, fut in enumerate(concurrent.futures.as_completed(futures), 1):
                i = futures[fut]
                results[i] = fut.result()
                note(i, n)
    if args.save and not todo:
        print("nothing left to run: the summary of the saved cases", file=sys.stderr)
    results_list = [results[k] for k in sorted(results)]
    meta = {"seed": args.seed, "cells": args.cells, "world_cells": min(args.world, args.cells),
            "jobs": args.jobs, "resumed_cases": len(done_cases),
            "wall_s": time.perf_counter() - wall0, "cpu_s": _cpu_s() - cpu0,
            "cpu": cpu_name(), "started": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(
                time.time() - (time.perf_counter() - wall0)))}
    summ = {"meta": meta, **{arm: rates(results_list, arm) for arm in
                             ("fixed", "adaptive", "world_fixed", "world_adaptive")}}
    if args.save:
        Path(args.save).write_text(json.dumps(json_safe({"summary": summ, "cases": results_list}),
                                              indent=1))
    if args.plot:
        from closed_loop_plot import campaign_figure
        campaign_figure(json.loads(json.dumps(json_safe(results_list))), args.plot)
    if args.json:
        print(json.dumps(json_safe(summ), indent=1))
    else:
        for arm in ("fixed", "adaptive", "world_fixed", "world_adaptive"):
            if summ[arm]:
                print(arm, json.dumps(json_safe(summ[arm])))
        print("meta", json.dumps(meta))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
