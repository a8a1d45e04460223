#!/usr/bin/env python3
"""Closed-loop campaign through the ROS 2 nodes: the fixed plan beside the adaptive planner.

Each cell is drawn as in ``closed_loop_campaign.py`` (k1, c2 x [0.7, 1.3], mass per length
x [0.8, 1.2], mould and tool friction [0, 0.3], movement 1-4, speed 1x or 2x the paper's
1 mm/s) and run twice by the three nodes in one process (``rheo-shaping cell --json``, a
ROS domain of its own): the simulator plays the drawn batch (``batch_k1`` ... on the params
file's cell), the planner and monitor know only the params file; once with the fixed plan,
once with ``--adaptive``.  Per arm: shaped (finished, no abort, no tear, Delta <= 5 mm),
aborts, tears (F_max >= F_break), the cycle time (the plan's end plus the params file's
settle time after its fixed plan), re-plans.  Progress with an ETA on stderr.

    .venv/bin/python benchmarks/closed_loop_nodes.py --cells 200 --seed 4301 --jobs 2 \\
        [--real-time-factor 20] [--json] [--save FILE.json] [--optimum] [--plot FILE.png]

``--optimum`` adds each cell's offline optimum (``adaptive.optimum``: the fastest plan that
meets both limits, computed knowing the true cell on the sheet model, in this process) and
the adaptive arm's median cycle time over it; ``--plot`` draws the shaped rate against the
material's deviation and the cycle time over the optimum.  With ``--cells`` no larger than
the cells a ``--save`` file holds, nothing is run: its figures are computed (a campaign cut
short is summarised on its first N cells, in the seed's order).

``--save`` is written after every run; a campaign started again with the same file, seed
and real-time factor runs only what it lacks (a campaign cut short resumes).

Each run's wall time depends on the machine's load: the figures say what ran beside them.
"""
from __future__ import annotations

import argparse
import json
import os
import queue
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import cpu_name  # noqa: E402
from closed_loop_campaign import draw  # noqa: E402

from rheo_shaping.jsonable import json_safe  # noqa: E402
from rheo_shaping.params.cell import CellParams  # noqa: E402
from rheo_shaping.planning.movement import movement_plan  # noqa: E402

BIN = Path(sys.executable).parent
PARAMS = """\
/**:
  ros__parameters:
    movement.number: {movement}
    movement.speed: {speed!r}
simulator:
  ros__parameters:
    batch_k1: {k1!r}
    batch_c2: {c2!r}
    batch_mass: {mass!r}
    batch_friction_mould: {friction_mould!r}
    batch_friction_tool: {friction_tool!r}
"""


def params_cell(d: dict) -> CellParams:
    base = CellParams()
    return replace(base, movement=replace(base.movement, number=d["movement"],
                                          speed=1e-3 * d["speed_factor"]))


def cell_json(d: dict, adaptive: bool, rtf: float, domain: int, folder: Path
              ) -> tuple[dict | None, dict]:
    """Draw ``d`` run once by ``rheo-shaping cell --json`` in ROS domain ``domain``: (its
    JSON, None on a failed run; {"wall_s": the run's wall time [s], "error": why})."""
    f = folder / f"cell_{domain}.yaml"
    f.write_text(PARAMS.format(speed=1e-3 * d["speed_factor"], **d))
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    cmd = [str(BIN / "rheo-shaping"), "cell", "--params", str(f), "--json",
           "--real-time-factor", f"{rtf:g}", "--timeout", "900"] + (["--adaptive"] * adaptive)
    t0 = time.monotonic()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = {"wall_s": time.monotonic() - t0}
    try:
        return json.loads(proc.stdout.strip().splitlines()[-1]), wall
    except (IndexError, json.JSONDecodeError):
        return None, dict(wall, error=f"exit {proc.returncode}: {proc.stderr[-800:]}")


def run_one(d: dict, adaptive: bool, rtf: float, domain: int, folder: Path) -> dict:
    """One cell run by the nodes; the figures of ``rheo-shaping cell --json``."""
    out, run = cell_json(d, adaptive, rtf, domain, folder)
    if out is None:
        return run
    wall = run["wall_s"]
    cell = params_cell(d)
    fixed = movement_plan(cell).plan.duration
    settle = max(cell.movement.process_time - fixed, 0.0)
    torn = out["F_max"] >= out["F_break"]
    shaped = out["finished"] and not out["aborted"] and not torn and out["delta"] <= 5e-3
    log = out.get("adaptive", [])
    return {"shaped": shaped, "aborted": out["aborted"], "torn": torn, "F_max": out["F_max"],
            "delta": out["delta"], "finished": out["finished"],
            "cycle_time": out["plan_duration"] + settle if shaped else float("inf"),
            "refreshes": len(log), "replans": sum(1 for e in log if e["switched"]),
            "dropped": sum(1 for e in log if e["replanned"] and not e["switched"]),
            "abort_reason": out["abort_reason"], "wall_s": wall,
            "x_real_time": out["achieved_factor"]}


def optimum(d: dict) -> dict:
    """The offline optimum of draw ``d`` (``closed_loop_campaign``'s yardstick)."""
    from closed_loop_campaign import cells
    from rheo_shaping.adaptive.loop import LoopConfig, replan_limits
    from rheo_shaping.adaptive.optimum import offline_optimum
    from rheo_shaping.adaptive.replan import ReplanStatus
    cell, true = cells(d)
    config = LoopConfig()
    limits = replan_limits(cell, config.detect_time, config.noise_sigma)
    opt = offline_optimum(true, cell, limits)
    ok = opt.status in (ReplanStatus.REPLANNED, ReplanStatus.KEPT)
    return {"status": opt.status.value,
            "cycle_time": opt.schedule.cycle_time if ok else float("nan")}


def key(adaptive: bool) -> str:
    return "adaptive" if adaptive else "fixed"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cells", type=int, default=200)
    ap.add_argument("--seed", type=int, default=4301)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--real-time-factor", type=float, default=20.0)
    ap.add_argument("--domain", type=int, default=120, help="first ROS domain id of the jobs")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--save", type=Path)
    ap.add_argument("--optimum", action="store_true",
                    help="each cell's offline optimum and the adaptive cycle time over it")
    ap.add_argument("--plot", type=Path, help="the campaign's figure (PNG)")
    a = ap.parse_args(argv)
    if a.cells < 1 or a.jobs < 1 or not 0 < a.real_time_factor <= 100:
        ap.error(f"--cells {a.cells}, --jobs {a.jobs}, --real-time-factor "
                 f"{a.real_time_factor}: expected >= 1, >= 1, (0, 100]")
    rng = np.random.default_rng(a.seed)
    draws = [draw(rng) for _ in range(a.cells)]
    tasks = [(i, arm) for i in range(a.cells) for arm in (False, True)]
    rows: dict = {i: {"draw": d} for i, d in enumerate(draws)}
    loads: list[float] = []
    if a.save and a.save.exists():
        old = json.loads(a.save.read_text())
        same = old["report"].get("seed") == a.seed and \
            old["report"].get("real_time_factor") == a.real_time_factor
        if not same:
            ap.error(f"--save {a.save}: another campaign's (seed, real-time factor): expected "
                     f"{a.seed}, {a.real_time_factor:g} to resume; give another file")
        for k, row in old["rows"].items():
            if int(k) < a.cells:
                rows[int(k)].update({arm: r for arm, r in row.items() if arm != "draw"})
        loads = old["report"].get("loads", [])
    tasks = [(i, arm) for i, arm in tasks if key(arm) not in rows[i]]
    t0, done = time.monotonic(), 0
    with tempfile.TemporaryDirectory() as tmp, ThreadPoolExecutor(a.jobs) as pool:
        free = queue.Queue()             # one ROS domain per running job, never shared
        for j in range(a.jobs):
            free.put(a.domain + j)

        def job(k: int, i: int, arm: bool) -> dict:
            domain = free.get()
            try:
                folder = Path(tmp) / str(k)
                folder.mkdir()
                return run_one(draws[i], arm, a.real_time_factor, domain, folder)
            finally:
                free.put(domain)
        futures = {pool.submit(job, k, i, arm): (i, arm) for k, (i, arm) in enumerate(tasks)}
        for fut in futures:
            i, arm = futures[fut]
            rows[i][key(arm)] = fut.result()
            done += 1
            loads.append(os.getloadavg()[0])
            if a.save:
                a.save.write_text(json.dumps(json_safe(
                    {"report": {"seed": a.seed, "real_time_factor": a.real_time_factor,
                                "partial": True, "loads": loads}, "rows": rows}), indent=1))
            el = time.monotonic() - t0
            print(f"[{done}/{len(tasks)}] cell {i} {key(arm)}: "
                  f"{'shaped' if rows[i][key(arm)].get('shaped') else 'not shaped'}"
                  f"; ETA {el / done * (len(tasks) - done):.0f} s", file=sys.stderr, flush=True)
    report = {"machine": f"{cpu_name()}, {os.cpu_count()} cores", "seed": a.seed,
              "cells": a.cells, "real_time_factor": a.real_time_factor, "jobs": a.jobs,
              "wall_s": time.monotonic() - t0,
              "load_average_median": float(np.median(loads)) if loads else None,
              "loads": loads}
    for arm in ("fixed", "adaptive"):
        rs = [rows[i][arm] for i in rows if arm in rows[i]]
        report[arm] = {k: sum(1 for r in rs if r.get(k)) for k in ("shaped", "aborted", "torn")}
        report[arm]["errors"] = sum(1 for r in rs if "error" in r)
    both = [rows[i] for i in rows if rows[i].get("fixed", {}).get("shaped")
            and rows[i].get("adaptive", {}).get("shaped")]
    report["cycle_ratio_median"] = (float(np.median([r["adaptive"]["cycle_time"]
                                                     / r["fixed"]["cycle_time"] for r in both]))
                                    if both else None)
    if a.optimum or a.plot:
        for i in rows:
            if "optimum" not in rows[i]:
                rows[i]["optimum"] = optimum(rows[i]["draw"])
        ratio = [rows[i]["adaptive"]["cycle_time"] / rows[i]["optimum"]["cycle_time"]
                 for i in rows if rows[i].get("adaptive", {}).get("shaped")
                 and np.isfinite(rows[i]["optimum"]["cycle_time"])]
        report["adaptive_cycle_over_optimum_median"] = (float(np.median(ratio)) if ratio
                                                        else None)
        report["optimum_infeasible"] = sum(1 for i in rows
                                           if not np.isfinite(rows[i]["optimum"]["cycle_time"]))
    if a.plot:
        from closed_loop_plot import campaign_figure
        done_rows = [dict(rows[i], **{arm: dict(rows[i][arm], cycle_time=(
            rows[i][arm]["cycle_time"] if rows[i][arm]["shaped"] else float("nan")))
            for arm in ("fixed", "adaptive")}) for i in rows
            if "fixed" in rows[i] and "adaptive" in rows[i]]
        campaign_figure(json.loads(json.dumps(json_safe(done_rows))), str(a.plot))
    if a.save:
        a.save.write_text(json.dumps(json_safe({"report": report, "rows": rows}), indent=1))
    shown = {k: v for k, v in report.items() if k != "loads"}
    print(json.dumps(json_safe(shown)) if a.json else
          "\n".join(f"{k}: {v}" for k, v in shown.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
