#!/usr/bin/env python3
"""The cost of one refresh of the closed loop (issue 43): estimate + re-plan, CPU time of
this process (``time.process_time``), per refresh of an adaptive run, against the budget
(20 % of the 2 s refresh period at x1 = 0.4 s; the whole period at x10 = 0.2 s).

    .venv-core/bin/python benchmarks/closed_loop_cost.py [--movement 1] [--factors K1 C2 M]
        [--json]

The load average at the start and end is printed beside: on a shared machine the CPU time
of a refresh grows with the other processes' (caches, turbo), less than the wall time.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import cpu_name  # noqa: E402

from rheo_shaping.adaptive.settle import material_cell  # noqa: E402
from rheo_shaping.adaptive.loop import LoopConfig, run_closed_loop  # noqa: E402
from rheo_shaping.params.cell import CellParams  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--movement", type=int, default=1)
    ap.add_argument("--factors", type=float, nargs=3, default=(1.0, 1.0, 1.0))
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    base = CellParams()
    cell = replace(base, movement=replace(base.movement, number=args.movement))
    true = material_cell(cell, np.array([95.0, 1300.0, 0.3125]) * np.array(args.factors))
    load0 = os.getloadavg()
    wall = time.perf_counter()
    r = run_closed_loop(true, cell, LoopConfig(adaptive=True))
    wall = time.perf_counter() - wall
    est = np.array([e.estimate.cost_s for e in r.events])
    rep = np.array([e.replan.cost_s if e.replan else 0.0 for e in r.events])
    tot = est + rep
    period = LoopConfig().refresh_period
    out = {"cpu": cpu_name(), "load_average_start": load0, "load_average_end": os.getloadavg(),
           "refreshes": int(tot.size), "refresh_period_s": period,
           "estimate_s": {"median": float(np.median(est)), "max": float(est.max())},
           "replan_s": {"median": float(np.median(rep)), "max": float(rep.max())},
           "total_s": {"median": float(np.median(tot)), "p95": float(np.percentile(tot, 95)),
                       "max": float(tot.max())},
           "share_of_period_x1_max": float(tot.max() / period),
           "share_of_period_x10_max": float(tot.max() / (period / 10)),
           "run_wall_s": wall, "cycle_time_s": r.cycle_time, "shaped": r.shaped}
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        for k, v in out.items():
            print(f"{k}: {v}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
